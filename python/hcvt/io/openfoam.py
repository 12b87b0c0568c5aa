"""OpenFOAM case: ``constant/polyMesh`` and the ``system/`` files its tools need.

The polyMesh format (OpenFOAM user guide, "Mesh description"): ``points`` (vectorField),
``faces`` (faceList; faceCompactList in binary), ``owner`` and ``neighbour`` (labelList),
``boundary`` (polyBoundaryMesh). OpenFOAM requires

- each face's normal pointing out of its owner, and owner < neighbour on interior faces;
- interior faces first, in upper-triangular order: sorted by owner, then by neighbour;
- boundary faces after them, grouped by patch; a patch is ``nFaces`` consecutive faces
  from ``startFace``.

A 2D mesh is extruded one cell thick along z, its front and back faces forming the patch
``frontAndBack`` of type ``empty``: OpenFOAM's way of solving in 2D.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt.mesh.merge import (
    BOUNDARY_FACES,
    SPLIT_REMOVED,
    merge_failing_boundary_faces,
    merged_boundary,
)
from hcvt.mesh.patches import boundary_patches
from hcvt.mesh.polymesh import PolyMesh

if TYPE_CHECKING:
    from hcvt.geometry.domain import Domain

#: Label and scalar sizes written in binary files (OpenFOAM's default build, and Debian's).
ARCH = "LSB;label=32;scalar=64"

_BANNER = "// Written by hcvt.\n"


def write_openfoam(
    mesh: PolyMesh,
    case: str | Path,
    *,
    domain: Domain | None = None,
    labels: ArrayLike | None = None,
    binary: bool = False,
    thickness: float | None = None,
    cell_data: dict[str, ArrayLike] | None = None,
    boundary_faces: str = "merged",
    site: ArrayLike | None = None,
) -> Path:
    """Write ``mesh`` as the OpenFOAM case directory ``case``.

    Parameters
    ----------
    mesh : PolyMesh
        A conforming mesh (checked with :meth:`PolyMesh.check`); its cells without faces
        (empty cells) are left out, the others renumbered in order.
    case : str or Path
        Directory; created if missing. Written: ``constant/polyMesh/{points, faces,
        owner, neighbour, boundary}``, ``system/{controlDict, fvSchemes, fvSolution}`` (so
        ``checkMesh -case DIR`` and ``foamToVTK`` run), and ``0/site`` (the site of each
        cell, a volScalarField) plus one ``0/<name>`` per ``cell_data`` entry.
    domain, labels
        Patches: see :func:`hcvt.mesh.patches.boundary_patches`. Every patch is of type
        ``wall``.
    binary : bool, default False
        Binary lists (``format binary``, 32-bit labels, 64-bit scalars: ``ARCH``); much
        faster to write and read for large meshes. Text otherwise, with every coordinate
        written to the 17 digits that round-trip.
    thickness : float, optional
        2D only: the extrusion's depth along z, L; default the mean cell size ``(A/n)^½``.
    cell_data : dict of str to array_like of shape (n_sites,), optional
        Per-site values (row ``i`` is site ``i``) written as volScalarFields, each cell
        taking its site's value.
    boundary_faces : {"merged", "exact"}
        How the boundary is written (a 2D mesh's boundary faces are its extruded edges;
        with ``"merged"`` those that fail are joined with their neighbours as in 3D).
        ``"merged"``, the
        default: the boundary pieces checkMesh would flag (small pieces at a cell's rim
        are skew; in a cell wrapping a reflex edge, its centre lies behind some pieces:
        face pyramids) are joined to neighbouring pieces of the same cell and patch until
        checkMesh's skewness and pyramid checks pass (:mod:`hcvt.mesh.merge`), after
        each cell in several parts (a thin tunnel crossing it) has given all but its
        largest to neighbours (:mod:`hcvt.mesh.parts`); other cells and interior faces
        are unchanged, but a merged face is not planar, so the
        volumes OpenFOAM computes for the cells that have one move slightly
        (``docs/results/checkmesh.txt``); ``laplacianFoam`` converges on it
        (:mod:`hcvt.io.solver`). ``"exact"``: every piece of an input triangle in a
        cell is its own planar face; the geometry is exact (checkMesh's total volume is
        the domain's) but checkMesh fails its skewness and pyramid checks. (``"split"``,
        cells cut by planes into parts that pass checkMesh, was removed: its parts made
        ``laplacianFoam`` diverge, issue 30.)
    site : array_like of int, shape (mesh.n_cells,), optional
        The site each cell of ``mesh`` belongs to (default: cell ``i`` is site ``i``),
        written as ``0/site``.

    Returns
    -------
    Path
        ``case``.

    Raises
    ------
    ValueError
        An unknown ``boundary_faces`` (``"split"`` says it was removed); a ``site`` of
        the wrong length.
    """
    if boundary_faces == "split":
        raise ValueError(SPLIT_REMOVED)
    if boundary_faces not in BOUNDARY_FACES:
        raise ValueError(f"boundary_faces must be one of {BOUNDARY_FACES}, got {boundary_faces!r}")
    mesh.check()
    site_of = np.arange(mesh.n_cells) if site is None else np.asarray(site, dtype=np.intp)
    if site_of.shape != (mesh.n_cells,):
        raise ValueError(f"site must have one entry per cell ({mesh.n_cells}), got {site_of.shape}")
    if mesh.periodic_partner is not None:
        return _write_periodic(mesh, Path(case), domain, site_of, cell_data, binary, thickness)
    if boundary_faces == "merged" and mesh.dim == 3:
        mesh, report = merged_boundary(mesh, domain, labels)
        if len(report.failing):
            warnings.warn(
                f"{len(report.failing)} boundary faces still fail checkMesh's skewness or "
                "face-pyramid check after merging",
                stacklevel=2,
            )
        mesh.check()  # still closed cells of positive volume
    patch, names = boundary_patches(mesh, domain, labels)
    compact, kept = mesh.compacted()
    fields = {"site": site_of[kept].astype(np.float64)}
    for name, values in (cell_data or {}).items():
        fields[name] = np.asarray(values, dtype=np.float64)[site_of[kept]]
    types = ["wall"] * len(names)
    if compact.dim == 2:
        compact, patch, names = _extrude(compact, patch, names, thickness)
        types.append("empty")
        if boundary_faces == "merged":
            compact, patch = _merged_sides(compact, patch)
    return _write_case(Path(case), compact, patch, names, types, fields, binary)


def _write_case(
    root: Path,
    mesh: PolyMesh,
    patch: NDArray[np.intp],
    names: list[str],
    types: list[str],
    fields: dict[str, NDArray[np.float64]],
    binary: bool,
    rank: NDArray[np.intp] | None = None,
    extra: dict[str, str] | None = None,
) -> Path:
    """The case of a compact 3D ``mesh``: polyMesh in OpenFOAM's order, system, fields.

    ``rank`` orders faces within patches (:func:`_upper_triangular`), ``extra`` adds
    entries to patches (:func:`_write_boundary`).
    """
    points, faces, owner, neighbour, sizes = _upper_triangular(mesh, patch, len(names), rank)
    poly = root / "constant" / "polyMesh"
    poly.mkdir(parents=True, exist_ok=True)
    fmt = "binary" if binary else "ascii"
    note = (
        f"nPoints:{len(points)} nCells:{mesh.n_cells} nFaces:{len(owner)} "
        f"nInternalFaces:{len(neighbour)}"
    )
    _write_list(poly / "points", "vectorField", points, fmt)
    _write_faces(poly / "faces", faces, fmt)
    _write_list(poly / "owner", "labelList", owner, fmt, note)
    _write_list(poly / "neighbour", "labelList", neighbour, fmt, note)
    _write_boundary(poly / "boundary", names, types, sizes, len(neighbour), extra)
    write_system(root)
    cyclic = frozenset(n for n, t in zip(names, types, strict=True) if t == "cyclic")
    for name, values in fields.items():
        _write_field(root / "0" / name, name, values, names, cyclic)
    return root


# ----------------------------------------------------------------------------- ordering
def _upper_triangular(
    mesh: PolyMesh,
    patch: NDArray[np.intp],
    n_patches: int,
    rank: NDArray[np.intp] | None = None,
) -> tuple[
    NDArray[np.float64],
    tuple[NDArray[np.intp], NDArray[np.intp]],
    NDArray[np.intp],
    NDArray[np.intp],
    NDArray[np.intp],
]:
    """Points, faces (offsets, vertices), owner, neighbour and patch sizes, reordered.

    OpenFOAM's order: interior faces with owner < neighbour sorted by (owner, neighbour),
    then the boundary faces patch by patch (by owner within a patch, or by ``rank`` (f,)
    when given: a cyclic patch's faces in the order of their twins').
    """
    owner, neighbour = mesh.owner.copy(), mesh.neighbour.copy()
    flip = mesh.interior & (owner > neighbour)
    owner[flip], neighbour[flip] = mesh.neighbour[flip], mesh.owner[flip]
    inner = mesh.interior
    within = owner if rank is None else np.where(inner, owner, rank)
    # Sort keys: interior faces first (patch -1), then by patch, owner, neighbour, index.
    order = np.lexsort((np.arange(mesh.n_faces), neighbour, within, np.where(inner, -1, patch)))
    sizes = mesh.face_sizes[order]
    offsets = np.zeros(len(order) + 1, dtype=np.intp)
    np.cumsum(sizes, out=offsets[1:])
    # Gather each face's vertices in the new order, reversed where owner and neighbour
    # swapped so that the normal still points out of the owner.
    start = mesh.face_offsets[order]
    within = np.arange(offsets[-1]) - np.repeat(offsets[:-1], sizes)
    reverse = np.repeat(flip[order], sizes)
    # A reversed loop keeps its first vertex: (v0, v_{k-1}, ..., v1).
    k = np.repeat(sizes, sizes)
    position = np.where(reverse, (k - within) % k, within)
    vertices = mesh.face_vertices[np.repeat(start, sizes) + position]
    n_inner = int(inner.sum())
    counts = np.bincount(patch[order][n_inner:], minlength=n_patches)
    return mesh.points, (offsets, vertices), owner[order], neighbour[order][:n_inner], counts


# ----------------------------------------------------------------------------- 2D
def _extrude(
    mesh: PolyMesh, patch: NDArray[np.intp], names: list[str], thickness: float | None
) -> tuple[PolyMesh, NDArray[np.intp], list[str]]:
    """A 2D mesh extruded to one layer of prisms ``[0, thickness]`` along z.

    Each edge becomes a quad (a0, b0, b1, a1), outward like its edge; each cell's boundary
    loops become its back face (z = thickness, counter-clockwise seen from +z) and front
    face (z = 0, reversed), in the patch ``frontAndBack``. A cell with a hole has its
    front and back triangulated (shapely's constrained Delaunay, on its own vertices).
    """
    p = len(mesh.points)
    volume = mesh.cell_geometry.volume
    depth = float(np.sqrt(volume.sum() / mesh.n_cells)) if thickness is None else thickness
    if not depth > 0:
        raise ValueError(f"thickness must be positive, got {thickness}")
    points = np.vstack(
        [
            np.column_stack([mesh.points, np.zeros(p)]),
            np.column_stack([mesh.points, np.full(p, depth)]),
        ]
    )
    a, b = mesh.face_vertices[0::2], mesh.face_vertices[1::2]
    sides = np.column_stack([a, b, b + p, a + p])
    caps: list[NDArray[np.intp]] = []
    cap_cell: list[int] = []
    for cell, pieces in enumerate(mesh.cell_polygons()):
        for ring in pieces:
            caps += [ring[::-1], ring + p]
            cap_cell += [cell, cell]
    cap_sizes = np.array([len(c) for c in caps], dtype=np.intp)
    offsets = np.concatenate([np.arange(0, 4 * len(a) + 1, 4), 4 * len(a) + np.cumsum(cap_sizes)])
    extruded = PolyMesh(
        points=points,
        face_offsets=offsets.astype(np.intp),
        face_vertices=np.concatenate([sides.ravel(), *caps]).astype(np.intp),
        owner=np.concatenate([mesh.owner, np.asarray(cap_cell, dtype=np.intp)]),
        neighbour=np.concatenate([mesh.neighbour, np.full(len(caps), -1, dtype=np.intp)]),
        boundary_element=np.concatenate([mesh.boundary_element, np.full(len(caps), -1)]),
        n_cells=mesh.n_cells,
    )
    front_back = np.full(len(caps), len(names), dtype=np.intp)
    return extruded, np.concatenate([patch, front_back]), [*names, "frontAndBack"]


def _merged_sides(mesh: PolyMesh, patch: NDArray[np.intp]) -> tuple[PolyMesh, NDArray[np.intp]]:
    """An extruded 2D mesh with its failing side faces merged, as a 3D mesh's boundary is.

    A cell that wraps around a corner of a hole has a small side face beyond the corner,
    seen from behind by its cell centre (an inverted face pyramid, a skew face); joined
    with its neighbouring side face of the same cell and patch it passes
    (:func:`hcvt.mesh.merge.merge_failing_boundary_faces`). The caps (``frontAndBack``)
    are never joined: no cap shares a patch with another face of its cell's boundary loop.
    A merged face keeps its representative's boundary element, which gives its patch.
    """
    side = mesh.boundary_element >= 0
    element_patch = np.full(int(mesh.boundary_element.max(initial=-1)) + 1, -1, dtype=np.intp)
    element_patch[mesh.boundary_element[side]] = patch[side]
    merged, report = merge_failing_boundary_faces(mesh, patch)
    if len(report.failing):
        warnings.warn(
            f"{len(report.failing)} side faces of the extruded mesh still fail checkMesh's "
            "skewness or face-pyramid check after merging",
            stacklevel=3,
        )
    merged, _ = merged.compacted()
    element = merged.boundary_element
    caps = patch.max(initial=0)  # frontAndBack, the last patch
    boundary = merged.neighbour < 0
    out = np.full(merged.n_faces, -1, dtype=np.intp)
    out[boundary] = np.where(element[boundary] >= 0, element_patch[element[boundary]], caps)
    return merged, out


# ----------------------------------------------------------------------------- files
def foam_header(
    cls: str, obj: str, fmt: str = "ascii", location: str = "", note: str | None = None
) -> str:
    """The ``FoamFile`` header of a file of class ``cls``, object ``obj``, in ``location``."""
    lines = [
        _BANNER,
        "FoamFile\n{\n",
        "    version     2.0;\n",
        f"    format      {fmt};\n",
    ]
    if fmt == "binary":
        lines.append(f'    arch        "{ARCH}";\n')
    lines.append(f"    class       {cls};\n")
    if note:
        lines.append(f'    note        "{note}";\n')
    lines += [f'    location    "{location}";\n', f"    object      {obj};\n", "}\n\n"]
    return "".join(lines)


def _location(path: Path) -> str:
    """``constant/polyMesh`` for a mesh file, else the directory's own name."""
    if path.parent.name == "polyMesh":
        return f"{path.parent.parent.name}/{path.parent.name}"
    return path.parent.name


def _write_list(path: Path, cls: str, values: NDArray, fmt: str, note: str | None = None) -> None:
    """A vectorField (rows of 3) or labelList (ints), text or binary."""
    head = foam_header(cls, path.name, fmt, _location(path), note)
    with path.open("wb") as out:
        out.write(head.encode("ascii"))
        out.write(f"{len(values)}\n(".encode("ascii"))
        if fmt == "binary":
            dtype = "<f8" if cls == "vectorField" else "<i4"
            out.write(np.ascontiguousarray(values, dtype=dtype).tobytes())
            out.write(b")\n")
        else:
            out.write(b"\n")
            out.write(_text(values).encode("ascii"))
            out.write(b")\n")


def _text(values: NDArray) -> str:
    """Rows ``(x y z)`` of a (k, 3) float array, or one int per line.

    Shortest round-trip digits, formatted by numpy in C rather than one Python call per
    number.
    """
    if values.ndim == 1:
        return "\n".join(values.astype(np.int64).astype(str).tolist()) + "\n"
    words = np.ascontiguousarray(values, dtype=np.float64).astype(str)
    rows = np.char.add(np.char.add(np.char.add("(", words[:, 0]), " "), words[:, 1])
    rows = np.char.add(np.char.add(np.char.add(rows, " "), words[:, 2]), ")")
    return "\n".join(rows.tolist()) + "\n"


def _write_faces(path: Path, faces: tuple[NDArray[np.intp], NDArray[np.intp]], fmt: str) -> None:
    """Write the faces: a faceList in text, a faceCompactList in binary.

    Text: ``k( v0 v1 ... )`` per line. Binary: the offsets list, then the vertices list.
    """
    offsets, vertices = faces
    sizes = np.diff(offsets)
    cls = "faceCompactList" if fmt == "binary" else "faceList"
    with path.open("wb") as out:
        out.write(foam_header(cls, "faces", fmt, "constant/polyMesh").encode("ascii"))
        if fmt == "binary":
            for values in (offsets, vertices):
                out.write(f"{len(values)}\n(".encode("ascii"))
                out.write(np.ascontiguousarray(values, dtype="<i4").tobytes())
                out.write(b")\n")
            return
        # Tokens "k(" v0 ... v_{k-1} ")" joined by spaces: OpenFOAM's tokenizer ignores
        # the blank between a bracket and a number.
        tokens = np.empty(len(vertices) + 2 * len(sizes), dtype=object)
        face_of = np.repeat(np.arange(len(sizes)), sizes)
        tokens[np.arange(len(vertices)) + 2 * face_of + 1] = vertices.astype(str).tolist()
        tokens[offsets[:-1] + 2 * np.arange(len(sizes))] = np.char.add(
            sizes.astype(str), "("
        ).tolist()
        tokens[offsets[1:] + 2 * np.arange(len(sizes)) + 1] = ")\n"
        out.write(f"{len(sizes)}\n(\n".encode("ascii"))
        out.write(" ".join(tokens.tolist()).replace("\n ", "\n").encode("ascii"))
        out.write(b")\n")


def _write_boundary(
    path: Path,
    names: list[str],
    types: list[str],
    sizes: NDArray[np.intp],
    start: int,
    extra: dict[str, str] | None = None,
) -> None:
    """The polyBoundaryMesh; ``extra`` adds entries to some patches (a cyclic's twin)."""
    entries = []
    for name, kind, size in zip(names, types, sizes.tolist(), strict=True):
        group = f"    inGroups        List<word> 1({kind});\n" if kind in ("wall", "cyclic") else ""
        entries.append(
            f"    {name}\n    {{\n        type            {kind};\n"
            + group.replace("    inGroups", "        inGroups")
            + f"        nFaces          {size};\n        startFace       {start};\n"
            + (extra or {}).get(name, "")
            + "    }\n"
        )
        start += size
    body = f"{len(names)}\n(\n" + "".join(entries) + ")\n"
    path.write_text(
        foam_header("polyBoundaryMesh", "boundary", "ascii", "constant/polyMesh") + body
    )


def _write_field(
    path: Path,
    name: str,
    values: NDArray[np.float64],
    patches: list[str],
    cyclic: frozenset[str] = frozenset(),
) -> None:
    """A dimensionless volScalarField.

    Its boundaries are zeroGradient (empty on the frontAndBack of an extruded 2D mesh,
    cyclic on the ``cyclic`` patches).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    words = values.astype(str).tolist()

    def kind(p: str) -> str:
        return "empty" if p == "frontAndBack" else "cyclic" if p in cyclic else "zeroGradient"

    boundary = "".join(
        f"    {p}\n    {{\n        type            {kind(p)};\n    }}\n" for p in patches
    )
    body = (
        "dimensions      [0 0 0 0 0 0 0];\n\n"
        f"internalField   nonuniform List<scalar>\n{len(words)}\n(\n"
        + "\n".join(words)
        + "\n)\n;\n\nboundaryField\n{\n"
        + boundary
        + "}\n"
    )
    path.write_text(foam_header("volScalarField", name, "ascii", "0") + body)


_CONTROL_DICT = """application     checkMesh;
startFrom       startTime;
startTime       0;
stopAt          endTime;
endTime         0;
deltaT          1;
writeControl    timeStep;
writeInterval   1;
purgeWrite      0;
writeFormat     ascii;
writePrecision  17;
writeCompression off;
timeFormat      general;
timePrecision   6;
runTimeModifiable false;
"""

_FV_SCHEMES = """ddtSchemes { default steadyState; }
gradSchemes { default Gauss linear; }
divSchemes { default none; }
laplacianSchemes { default Gauss linear corrected; }
interpolationSchemes { default linear; }
snGradSchemes { default corrected; }
"""

_FV_SOLUTION = """solvers {}
SIMPLE { nNonOrthogonalCorrectors 0; }
"""


def write_system(root: Path) -> None:
    """Minimal ``system/`` dictionaries, enough for checkMesh, foamToVTK and paraFoam.

    A solver needs its own schemes and solvers.
    """
    system = root / "system"
    system.mkdir(parents=True, exist_ok=True)
    for name, body in (
        ("controlDict", _CONTROL_DICT),
        ("fvSchemes", _FV_SCHEMES),
        ("fvSolution", _FV_SOLUTION),
    ):
        (system / name).write_text(foam_header("dictionary", name, "ascii", "system") + body)


# ----------------------------------------------------------------------------- periodic
_AXES = "xyz"


def _write_periodic(
    mesh: PolyMesh,
    root: Path,
    domain: Domain | None,
    site_of: NDArray[np.intp],
    cell_data: dict[str, ArrayLike] | None,
    binary: bool,
    thickness: float | None,
) -> Path:
    """Write a mesh of a periodic box (:mod:`hcvt.mesh.periodic`).

    Each pair of opposite image shifts ``±k`` is a pair of ``cyclic`` patches
    ``cyclic_<k>`` (``cyclic_xpym`` for (1, -1, 0); ``transform translational``,
    ``separationVector`` the shift from the patch's faces to its twin's),
    face ``q`` of one the twin of face ``q`` of the other, its first point the image of
    the other's first point; faces on the sides of non-periodic axes in ``<axis>lo`` and
    ``<axis>hi`` (``wall``). The boundary faces are written exact (planar pieces: a box
    needs no merging).
    """
    if domain is None:
        raise ValueError("a periodic mesh needs its domain (the box) to be written")
    lo, hi = domain.bounds
    period = np.where(np.array(domain.periodic), hi - lo, 0.0)
    partner, image = mesh.periodic_partner, mesh.periodic_image
    assert partner is not None and image is not None
    compact, kept = mesh.compacted()
    d = mesh.dim
    names: list[str] = []
    types: list[str] = []
    extra: dict[str, str] = {}
    patch = np.full(mesh.n_faces, -1, dtype=np.intp)
    rank = np.arange(mesh.n_faces, dtype=np.intp)
    wall = (mesh.neighbour < 0) & (partner < 0)
    if np.any(wall):
        side = _wall_side(mesh, lo, hi, wall)
        for code in np.unique(side[wall]).tolist():
            names.append(f"{_AXES[code // 2]}{'lo' if code % 2 == 0 else 'hi'}")
            types.append("wall")
            patch[wall & (side == code)] = len(names) - 1
    periodic = np.flatnonzero(partner >= 0)
    shifts = np.unique(image[periodic], axis=0)
    for k in shifts:
        first = next(v for v in k.tolist() if v != 0)
        if first < 0:
            continue  # the twin patch of +k
        these = periodic[np.all(image[periodic] == k, axis=1)]
        twins = partner[these]
        name, twin = _cyclic_name(k), _cyclic_name(-k)
        for members, label, other, sign in ((these, name, twin, -1.0), (twins, twin, name, 1.0)):
            names.append(label)
            types.append("cyclic")
            patch[members] = len(names) - 1
            vector = sign * k * period
            words = " ".join(repr(float(x)) for x in (*vector, 0.0)[:3])
            extra[label] = (
                "        matchTolerance  0.0001;\n"
                f"        neighbourPatch  {other};\n"
                "        transform       translational;\n"
                f"        separationVector ({words});\n"
            )
        rank[twins] = these  # each twin right after... in its own patch, in this order
    fields = {"site": site_of[kept].astype(np.float64)}
    for name, values in (cell_data or {}).items():
        fields[name] = np.asarray(values, dtype=np.float64)[site_of[kept]]
    if d == 2:
        n_faces = compact.n_faces
        compact, patch, names = _extrude(compact, patch, names, thickness)
        types.append("empty")
        caps = compact.n_faces - n_faces
        rank = np.concatenate([rank, np.arange(n_faces, compact.n_faces)])
        partner = np.concatenate([partner, np.full(caps, -1, dtype=np.intp)])
        image = np.vstack(
            [np.column_stack([image, np.zeros(len(image), np.int8)]), np.zeros((caps, 3), np.int8)]
        )
        period = np.append(period, 0.0)
    compact = _twins_aligned(compact, partner, image, period)
    return _write_case(root, compact, patch, names, types, fields, binary, rank, extra)


def _cyclic_name(k: NDArray[np.int8]) -> str:
    """``cyclic_xpym`` for the image shift (1, -1, 0) (p plus, m minus; a word)."""
    return "cyclic_" + "".join(
        f"{_AXES[a]}{'p' if v > 0 else 'm'}{abs(v) if abs(v) > 1 else ''}"
        for a, v in enumerate(k.tolist())
        if v != 0
    )


def _wall_side(
    mesh: PolyMesh, lo: NDArray[np.float64], hi: NDArray[np.float64], wall: NDArray[np.bool_]
) -> NDArray[np.intp]:
    """For each wall face, ``2 * axis + (0 at lo, 1 at hi)``; -1 elsewhere."""
    centre = mesh.face_geometry.centre
    gap = np.concatenate([np.abs(centre - lo), np.abs(centre - hi)], axis=1)
    best = np.argmin(gap, axis=1)
    axis, at_hi = best % mesh.dim, best // mesh.dim
    return np.where(wall, 2 * axis + at_hi, -1).astype(np.intp)


def _twins_aligned(
    mesh: PolyMesh,
    partner: NDArray[np.intp],
    image: NDArray[np.int8],
    period: NDArray[np.float64],
) -> PolyMesh:
    """``mesh`` with its twin faces rotated to start at their twins' first points.

    Each periodic face of negative shift (the twin patches) starts at the image of its
    twin's first point: OpenFOAM matches the points of coupled faces in order.
    """
    vertices = mesh.face_vertices.copy()
    offsets = mesh.face_offsets
    first = np.array([next((v for v in k if v != 0), 0) for k in image.tolist()])
    for f in np.flatnonzero((partner >= 0) & (first < 0)).tolist():
        g = int(partner[f])
        target = mesh.points[vertices[offsets[g]]] - image[g] * period
        loop = vertices[offsets[f] : offsets[f + 1]]
        start = int(np.argmin(np.sum((mesh.points[loop] - target) ** 2, axis=1)))
        vertices[offsets[f] : offsets[f + 1]] = np.roll(loop, -start)
    return PolyMesh(
        points=mesh.points,
        face_offsets=offsets,
        face_vertices=vertices,
        owner=mesh.owner,
        neighbour=mesh.neighbour,
        boundary_element=mesh.boundary_element,
        n_cells=mesh.n_cells,
        periodic_partner=partner,
        periodic_image=image,
    )
