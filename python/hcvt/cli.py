"""The ``hcvt`` command line: CVTs of built-in shapes, polygons and meshes.

hcvt run star -n 2000 --plot star.png
hcvt run polygon.geojson -n 10000 --method newton --init halton --out sites.npy
hcvt run bunny.off -n 50000 --mesh case/ --cells cells.vtu
hcvt run bunny.off -n 50000 --method newton --mesh case/ --mesh-boundary exact
hcvt run bunny.off --surface -n 20000 --out remeshed.ply
hcvt run square -n 1033 --method regular --moves 60 --plot square.png
hcvt run sphere -n 2562 --radius 6371229 --out base_mesh.nc
hcvt run unit-square -n 5000 --density "1 + 99*x^2" --plot graded.png
hcvt show result.json --plot cells.png
hcvt reproduce table4 --runs 10 --out results
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import json
import os
import sys
import time
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import click
import numpy as np
from shapely.geometry import MultiPolygon, Polygon

import hcvt
from hcvt import plot as pictures
from hcvt.density import Polynomial, SizingField
from hcvt.distributed import DEFAULT_SITES_PER_PARTITION, partitioned_cvt, partitioned_voronoi
from hcvt.experiments import reproduce as run_experiment
from hcvt.geometry.shapes import BUILTIN, builtin_domain
from hcvt.io.readers import read_polygon_and_crs
from hcvt.lazy import load
from hcvt.mesh import merged_boundary, mesh_quality
from hcvt.optimise import RULES, capacity_method, default_tol, fastest_method
from hcvt.seeding.sphere import icosahedral_level
from hcvt.surface.quality import HausdorffWarning

METHODS = ("hierarchical", "regular", "lbfgs", "newton", "lloyd", "monte-carlo", "voronoi")
OPTIMISERS = ("lbfgs", "newton", "lloyd")
INITS = ("random", "halton", "hammersley", "lattice", "fibonacci", "icosahedral")
#: The built-in sphere, of radius --radius (not a shape of hcvt.geometry.shapes: it has one).
SPHERE = "sphere"
#: Built-in boxes (hcvt.Domain.box), periodic with --periodic: the unit cube and square.
BOXES = {"box": 3, "box2d": 2}


class _OneLineErrors(click.Group):
    """Print library errors as a readable message and exit with status 2: no traceback."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except (ValueError, FileNotFoundError, NotImplementedError, OSError, ImportError) as err:
            # The library speaks of its keyword argument; here the option does the same.
            message = str(err).replace("repair=True", "--repair")
            click.echo(f"hcvt: error: {message}", err=True)
            sys.exit(2)


@click.group(cls=_OneLineErrors)
@click.version_option(package_name="hcvt")
def main() -> None:
    """Regular centroidal Voronoi tessellations of polygons and closed meshes."""


def _read_region(path: str) -> Polygon:
    """The lon/lat Polygon (degrees) of a GeoJSON or WKT file, read as `load_domain` reads them.

    A region of the sphere is one polygon (holes are islands); a file declaring a CRS other
    than longitude/latitude is refused rather than read as degrees.
    """
    polygon, crs = read_polygon_and_crs(Path(path))
    if crs is not None and not _is_lonlat(crs):
        raise click.UsageError(
            f"--region {path}: coordinates in {crs}; a region is lon/lat degrees"
        )
    if isinstance(polygon, MultiPolygon):
        count = len(polygon.geoms)
        raise click.UsageError(f"--region {path}: {count} polygons; a region of the sphere is one")
    return polygon


def _is_lonlat(crs: str) -> bool:
    """Whether a GeoJSON ``crs`` name means longitude/latitude in degrees (CRS84, EPSG:4326)."""
    return crs.upper().endswith(("CRS84", ":4326"))


def _load(
    input_: str,
    repair: bool,
    radius: float = 1.0,
    periodic: bool = False,
    region: str | None = None,
):
    if region is not None and input_ != SPHERE:
        raise click.UsageError(f"--region bounds a region of INPUT sphere, not of {input_!r}")
    if region is not None:
        return hcvt.Domain.sphere(radius, region=_read_region(region))

    if input_ in BOXES:
        d = BOXES[input_]
        return hcvt.Domain.box(np.zeros(d), np.ones(d), periodic=periodic)
    if periodic:
        raise click.UsageError(f"--periodic takes the boxes {', '.join(BOXES)}, not {input_!r}")
    if input_ == SPHERE:
        return hcvt.Domain.sphere(radius)
    if input_ in BUILTIN:
        return builtin_domain(input_)
    if not Path(input_).suffix and not Path(input_).exists():
        known = ", ".join(sorted([*BUILTIN, SPHERE, *BOXES]))
        raise ValueError(f"{input_!r} is no file and no built-in shape ({known})")
    return hcvt.load_domain(input_, repair=repair)


@main.command()
@click.argument("input_", metavar="INPUT")
@click.option("-n", "--sites", "n", type=int, required=True, help="Number of sites.")
@click.option(
    "--method",
    type=click.Choice(METHODS),
    default=None,
    help="[default: hierarchical; on the sphere the fastest optimiser it takes, hierarchical "
    "with --density]",
)
@click.option(
    "--init",
    type=click.Choice(INITS),
    default=None,
    help="Initial sites (fibonacci, icosahedral: the sphere only) [default: random; on the "
    "sphere icosahedral when N = 10*4^k + 2, else fibonacci, and random with --density].",
)
@click.option(
    "--radius",
    type=float,
    default=1.0,
    show_default=True,
    help="INPUT sphere: its radius; lengths and areas of --out .nc in its units (MPAS-A "
    "grid files: 1, scaled by the model; MPAS-Ocean: 6371229 m, MPAS-Tools' Earth).",
)
@click.option(
    "--region",
    "region_path",
    default=None,
    help="INPUT sphere: a region of it, a GeoJSON Polygon in lon/lat degrees (its first "
    "feature; holes are islands; edges are great-circle arcs): a regional ocean.",
)
@click.option(
    "--periodic",
    is_flag=True,
    help="INPUT box (the unit cube) or box2d (the unit square): periodic along every axis.",
)
@click.option(
    "--volumes",
    "volumes_spec",
    default=None,
    help="Prescribed cell volumes (a capacity-constrained CVT of power cells; --method lbfgs "
    "on the transport cost, the default, or lloyd, Bourne et al.'s alternation): "
    "lognormal:SIGMA (drawn from --seed, log-normal with that sigma) or FILE (.npy, or one "
    "value per line); relative sizes, scaled to the domain's volume.",
)
@click.option(
    "--volume-tol",
    type=float,
    default=1e-8,
    show_default=True,
    help="With --volumes: every cell's volume within this of its target, relatively.",
)
@click.option("--subdivisions", type=int, default=None, help="Hierarchy levels s.")
@click.option(
    "--optimiser",
    type=click.Choice(OPTIMISERS),
    default=None,
    help="Optimiser of every hierarchy level or of the regular method's CVTs [default: the "
    "fastest the domain takes: newton, or lbfgs on periodic boxes, with a sampled "
    "density or --scheduler].",
)
@click.option(
    "--moves",
    type=int,
    default=60,
    show_default=True,
    help="Regular method: defect-relaxation moves after the best-posed lattice.",
)
@click.option("--seed", type=int, default=0, show_default=True)
@click.option(
    "--rule",
    type=click.Choice(RULES),
    default="gap",
    show_default=True,
    help="Stop on the scale-free RMS gap |x-c|/V^(1/d), or on the paper's ‖g‖/‖X‖.",
)
@click.option(
    "--tol", type=float, default=None, help="The rule's tolerance [default: 1e-7 gap, 1e-10 paper]."
)
@click.option("--max-iter", type=int, default=10_000, show_default=True)
@click.option("--repair", is_flag=True, help="Repair an invalid polygon or mesh first.")
@click.option(
    "--surface",
    is_flag=True,
    help="Remesh the triangle surface INPUT with exactly N vertices (hcvt.remesh: a "
    "restricted CVT by --method lbfgs or lloyd, then the restricted Delaunay triangles); "
    "--out writes the mesh (.ply, .off, .obj, .vtk, .vtu, .msh in double precision by "
    "meshio; .stl, single by its format, by trimesh).",
)
@click.option(
    "--features",
    type=float,
    default=None,
    help="With --surface: keep the sharp edges, those whose triangles' normals differ by "
    "more than this many degrees (hcvt.remesh(features=...)).",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False),
    help="Sites: .npy or .csv; on the sphere also .nc, an MPAS mesh file (hcvt.write_mpas).",
)
@click.option(
    "--cells",
    "cells_path",
    type=click.Path(dir_okay=False),
    help="Cells file: .vtu (polyhedra / polygons; with --surface the restricted Voronoi cells' "
    "pieces), .geojson (2D), .ply (3D triangles); "
    "with --scheduler, .pvtu: one .vtu piece per part written by its worker, in the "
    "directory named like the file.",
)
@click.option(
    "--mesh",
    "mesh_dir",
    type=click.Path(file_okay=False),
    help="OpenFOAM case directory to write the conforming mesh into.",
)
@click.option(
    "--mesh-boundary",
    type=click.Choice(["merged", "exact"]),
    default="merged",
    show_default=True,
    help="--mesh, 3D: merged (boundary pieces joined into larger, non-planar faces until "
    "checkMesh's skewness and pyramid checks pass; cell volumes as OpenFOAM computes them "
    "move slightly), exact (each piece of an input triangle in a cell is a planar face; "
    "checkMesh flags small rim pieces as skew).",
)
@click.option("--summary", type=click.Path(dir_okay=False), help="Summary JSON file.")
@click.option("--plot", type=click.Path(dir_okay=False), help="PNG of the cells by G.")
@click.option(
    "--scheduler",
    is_flag=False,
    flag_value="local",
    default=None,
    help="Partition over dask.distributed: a scheduler ADDRESS, or alone for a LocalCluster "
    "(voronoi, lbfgs, lloyd).",
)
@click.option(
    "--sites-per-partition",
    type=int,
    default=None,
    help="With --scheduler: most sites per part [default: 200000].",
)
@click.option(
    "--density",
    "density_spec",
    default=None,
    help="Density rho: a polynomial of degree <= 2 such as '1 + 99*x^2 - 3*x*y' (read by "
    "a parser, never evaluated as Python), or FILE.py:NAME, a vectorised function "
    "rho(points) in your own Python file (the file is run to import it).",
)
@click.option(
    "--sizing",
    "sizing_spec",
    default=None,
    help="Target spacing h(x) as FILE.py:NAME (rho = h^-(d+2)); instead of --density.",
)
@click.option(
    "--quadrature-degree",
    type=click.IntRange(1, 5),
    default=4,
    show_default=True,
    help="Degree of the simplex rule that samples a function density.",
)
def run(
    input_: str,
    n: int,
    method: str | None,
    init: str | None,
    radius: float,
    region_path: str | None,
    periodic: bool,
    volumes_spec: str | None,
    volume_tol: float,
    subdivisions: int | None,
    optimiser: str | None,
    moves: int,
    seed: int,
    rule: str,
    tol: float | None,
    max_iter: int,
    repair: bool,
    surface: bool,
    features: float | None,
    out: str | None,
    cells_path: str | None,
    mesh_dir: str | None,
    mesh_boundary: str,
    summary: str | None,
    plot: str | None,
    scheduler: str | None,
    sites_per_partition: int | None,
    density_spec: str | None,
    sizing_spec: str | None,
    quadrature_degree: int,
) -> None:
    """CVT of N sites in INPUT: a built-in shape (square, star, sphere, ...) or a file."""
    if surface:
        _remesh(input_, n, method, seed, tol, max_iter, out, summary, features, cells_path)
        return
    if features is not None:
        raise click.UsageError("--features keeps sharp edges in remeshing: it needs --surface")
    if scheduler is not None and method not in PARTITIONED:
        raise click.UsageError(
            f"--scheduler runs the methods {', '.join(PARTITIONED)}, not {method!r}"
        )
    pieces = cells_path is not None and Path(cells_path).suffix.lower() == ".pvtu"
    if pieces and scheduler is None:
        raise click.UsageError("--cells .pvtu (one piece per part) needs --scheduler")
    if volumes_spec is not None:
        if method not in (None, "lloyd", "lbfgs") or scheduler is not None:
            raise click.UsageError(
                "--volumes takes --method lloyd (Bourne et al.'s alternation) or lbfgs, in one "
                f"process, not --method {method}" + (" with --scheduler" if scheduler else "")
            )
        method = capacity_method(method)
    domain = _load(input_, repair, radius, periodic, region_path)
    density = _density(density_spec, sizing_spec, domain.dim)
    method, init = _defaults(domain, n, method, init, density)
    _check_outputs(domain, out, plot)
    weighted: dict[str, Any] = (
        {} if density is None else {"density": density, "quadrature_degree": quadrature_degree}
    )
    if domain.repair_report is not None:
        click.echo(str(domain.repair_report))
    optimiser = optimiser or fastest_method(domain, density, partitioned=scheduler is not None)
    start = time.perf_counter()
    iterations: int | None = None
    history: dict[str, Any] | None = None
    if method == "hierarchical":
        result = hcvt.hierarchical_cvt(
            domain,
            n,
            subdivisions,
            init=init,
            seed=seed,
            rule=rule,
            tol=tol,
            max_iter=max_iter,
            method=optimiser,
            **weighted,
        )
        sites, diagram = result.sites, result.diagram
        iterations = sum(level.iterations for level in result.levels)
        history = result.levels[-1].history
    elif method == "regular":
        if density is not None:
            raise click.UsageError("--density/--sizing with --method regular is not offered yet")
        regular = hcvt.regular_cvt(
            domain,
            n,
            seed=seed,
            moves=moves,
            method=optimiser,
            rule=rule,
            tol=tol,
            max_iter=max_iter,
        )
        sites, diagram = regular.sites, regular.diagram
        iterations = regular.relaxation.moves
    else:
        graded = {"density": density} if density is not None and init != "lattice" else {}
        sites = hcvt.initialise(domain, n, method=init, seed=seed, **graded)
        partitioned = _client(scheduler) if scheduler is not None else contextlib.nullcontext()
        with partitioned as client:
            extra = weighted
            if volumes_spec is not None:
                volumes = _volumes(volumes_spec, n, seed)
                extra = {**weighted, "volumes": volumes, "normalise": True}
                extra["volume_tol"] = volume_tol
            if client is not None:
                extra = {**weighted, "client": client, "sites_per_partition": sites_per_partition}
            if pieces:
                # Each part's cells written where they are, then the arrays gathered.
                extra = {"cells_pvtu": cells_path, **extra}
            if method == "voronoi":
                diagram = _voronoi(domain, sites, **extra)
            elif method == "monte-carlo":
                mc = hcvt.global_monte_carlo(
                    domain, sites, seed=seed, rule=rule, tol=tol, progress=True, **weighted
                )
                sites, diagram, iterations = mc.sites, mc.diagram, mc.iterations
            else:
                run = _cvt(
                    domain,
                    sites,
                    method=method,
                    rule=rule,
                    tol=tol,
                    max_iter=max_iter,
                    progress=True,
                    **extra,
                )
                sites, diagram, iterations = run.sites, run.diagram, run.iterations
                history = run.history
    seconds = time.perf_counter() - start
    info: dict[str, Any] = {
        "input": input_,
        "method": method,
        "optimiser": optimiser if method in ("hierarchical", "regular") else None,
        "init": "posed lattice" if method == "regular" else init,
        "n": int(diagram.n),
        "mean_G": diagram.mean_G,
        "energy": diagram.energy,
        "iterations": iterations,
        "seconds": seconds,
        "seed": seed,
        "density": None if density is None else repr(density),
    }
    if domain.is_sphere:
        info["radius"] = domain.radius
    if region_path is not None:
        info["region"] = region_path
    found = None if domain.is_sphere else hcvt.defects(diagram)
    if found is not None:
        info.update(found.summary())
    if method != "voronoi":
        info["rule"] = rule
        info["tol"] = default_tol(rule) if tol is None else tol
    if history is not None:
        info.update({key: _scalar(history[key][-1]) for key in CONVERGENCE_FIELDS})
    if history is not None and "max_volume_error" in history:
        info["volumes"] = volumes_spec
        info["max_volume_error"] = _scalar(history["max_volume_error"][-1])
        info["newton_steps"] = int(np.sum(history["newton_steps"]))
    click.echo(
        f"n = {info['n']}  mean G = {info['mean_G']:.6f}  energy = {info['energy']:.6g}  "
        f"iterations = {iterations}  seconds = {seconds:.2f}"
    )
    if found is not None:
        click.echo(
            f"interior defects = {found.number} of {found.interior_cells} interior cells "
            f"({100 * found.fraction:.1f}%), {found.deep_number} away from the boundary layer"
        )
    elif not domain.is_sphere_region:
        info["sphere_quality"] = _sphere_quality(diagram)
    if history is not None:
        click.echo(
            f"rule = {rule}  RMS gap = {info['rms_gap']:.2e}  max gap = {info['max_gap']:.2e}  "
            f"|g|/|X| = {info['grad_norm']:.2e}  pinned = {info['pinned']}"
        )
    if "max_volume_error" in info:
        click.echo(
            f"volumes ({volumes_spec}): max relative error = {info['max_volume_error']:.2e}  "
            f"Newton steps = {info['newton_steps']}"
        )
    if out and Path(out).suffix.lower() == ".nc":
        hcvt.write_mpas(diagram, out)
        info["mpas_mesh"] = str(out)
    elif out:
        _write_sites(Path(out), sites)
        info["sites"] = str(out)
    if cells_path or mesh_dir:
        info.update(_write_meshes(diagram, cells_path, mesh_dir, mesh_boundary))
    if plot:
        _plot(diagram, plot)
    if summary:
        Path(summary).write_text(json.dumps(info, indent=2))


#: ``run --surface``: the options it reads (the others are refused), the optimisers it takes.
SURFACE_OPTIONS = {
    *("input_", "n", "method", "seed", "tol", "max_iter", "surface", "out", "summary"),
    *("features", "cells_path"),
}
SURFACE_METHODS = ("lbfgs", "lloyd")


def _remesh(
    input_: str,
    n: int,
    method: str | None,
    seed: int,
    tol: float | None,
    max_iter: int,
    out: str | None,
    summary: str | None,
    features: float | None = None,
    cells_path: str | None = None,
) -> None:
    """``run --surface``: :func:`hcvt.remesh` of the mesh file INPUT, its quality printed.

    ``--cells`` (.vtu, .ply) writes the final diagram's restricted Voronoi cells.
    """
    ctx = click.get_current_context()
    given = sorted(
        f"--{name.replace('_', '-')}"
        for name in ctx.params
        if name not in SURFACE_OPTIONS
        and ctx.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT
    )
    if given:
        raise click.UsageError(f"--surface does not take {', '.join(given)}")
    if method is not None and method not in SURFACE_METHODS:
        raise click.UsageError(f"--surface remeshes by --method lbfgs or lloyd, not {method!r}")
    if out and Path(out).suffix.lower() not in SURFACE_WRITERS:
        raise ValueError(
            f"--out with --surface writes a mesh ({', '.join(SURFACE_WRITERS)}), got {out}"
        )
    domain = hcvt.load_domain(input_, surface=True)
    # --max-iter's default is the volume CVTs'; remesh has its own unless one is given.
    limits: dict[str, Any] = {} if tol is None else {"tol": tol}
    if ctx.get_parameter_source("max_iter") is not click.core.ParameterSource.DEFAULT:
        limits["max_iter"] = max_iter
    result = hcvt.remesh(
        domain, n, seed=seed, method=method or "lbfgs", features=features, **limits
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", HausdorffWarning)  # printed as a range instead
        q = result.quality
    hausdorff = (
        f"{q.hausdorff:.3f}% of the diagonal"
        if q.hausdorff_certified
        else f"between {q.hausdorff:.3f}% and {q.hausdorff_bound:.3f}% of the diagonal (not "
        "certified: the search ran out of nearest points)"
    )
    click.echo(
        f"n = {q.vertices}  triangles = {q.faces}  iterations = {result.iterations} "
        f"({result.cvt.stop_reason})  seconds = {result.seconds:.2f}"
    )
    click.echo(
        f"Q min {q.q_min:.3f} mean {q.q_mean:.3f}  angle min {q.angle_min:.1f} deg  "
        f"{q.below_30:.2f}% of angles < 30 deg  Hausdorff {hausdorff}  "
        f"{'closed' if q.closed else 'manifold' if q.manifold else 'NOT manifold'}, "
        f"genus {q.genus}, {q.components} component(s)"
    )
    for defect in result.defects:
        click.echo(f"defect: {defect}")
    info: dict[str, Any] = {
        "input": input_,
        "surface": True,
        "method": method or "lbfgs",
        "seed": seed,
        "features": features,
        "iterations": result.iterations,
        "stop_reason": result.cvt.stop_reason,
        "seconds": result.seconds,
        "quality": dataclasses.asdict(q),
        "defects": result.defects,
    }
    if out:
        SURFACE_WRITERS[Path(out).suffix.lower()](Path(out), result.vertices, result.faces)
        info["mesh"] = str(out)
    if cells_path:
        hcvt.io.write_cells(result.cvt.diagram, cells_path)
        info["cells"] = str(cells_path)
    if summary:
        Path(summary).write_text(json.dumps(info, indent=2, default=str))


def _write_trimesh(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    trimesh = load("trimesh")
    trimesh.Trimesh(vertices, faces, process=False).export(path)


def _write_meshio(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    meshio = load("meshio")
    # int32 indices: PLY has no 64-bit integers (meshio would warn and cast).
    meshio.write(path, meshio.Mesh(vertices, [("triangle", faces.astype(np.int32))]))


#: ``run --surface --out``: the writer of each suffix.
SURFACE_WRITERS = {
    **dict.fromkeys((".ply", ".off", ".obj", ".vtk", ".vtu", ".msh"), _write_meshio),
    ".stl": _write_trimesh,
}


def _defaults(
    domain: Any, n: int, method: str | None, init: str | None, density: Any = None
) -> tuple[str, str]:
    """--method and --init as given, or their defaults for the domain (see their help)."""
    if domain.is_sphere_region:
        return method or "lbfgs", init or "random"  # no Hessian nor hierarchy there yet
    if domain.is_sphere:
        fits = icosahedral_level(n) is not None
        uniform = "icosahedral" if fits else "fibonacci"
        if density is not None:
            # The hierarchy of the density from a graded random level 0: on the 4:1 band
            # (2,584 cells) 0.76x the seconds of L-BFGS from a graded random start, 280
            # cells not hexagons against 378 (docs/guide/sphere.md, under load).
            return method or "hierarchical", init or "random"
        return method or fastest_method(domain, density), init or uniform
    return method or "hierarchical", init or "random"


def _check_outputs(domain: Any, out: str | None, plot: str | None) -> None:
    """Refuse, before any work, outputs the domain does not have."""
    if out and Path(out).suffix.lower() == ".nc" and not domain.is_sphere:
        raise ValueError("--out .nc writes an MPAS mesh, for INPUT sphere only")
    if out and Path(out).suffix.lower() == ".nc" and domain.is_sphere_region:
        raise NotImplementedError("--out .nc (an MPAS mesh) of a --region is not implemented yet")
    if plot and domain.is_sphere:
        raise ValueError(
            "--plot draws planar and solid cells; view spherical ones with "
            "hcvt.voronoi(...).to_pyvista()"
        )


def _sphere_quality(diagram: Any) -> dict[str, Any]:
    """Print the spherical mesh's quality as MPAS users read it; the summary's entry."""
    quality = hcvt.sphere_quality(diagram).summary()
    sides = ", ".join(f"{count} with {k}" for k, count in quality["sides"].items())
    angles = f"{quality['triangle_angle_min_deg']:.1f}-{quality['triangle_angle_max_deg']:.1f}"
    click.echo(
        f"cells by sides: {sides}  cell quality (shortest/longest edge) min "
        f"{quality['cell_quality_min']:.3f}  triangle angles {angles} deg "
        f"({quality['obtuse_triangles']} obtuse)  "
        f"grid spacing {quality['grid_spacing_min']:.4g}-{quality['grid_spacing_max']:.4g}"
    )
    return quality


def _write_meshes(
    diagram: Any, cells_path: str | None, mesh_dir: str | None, mesh_boundary: str = "merged"
) -> dict[str, Any]:
    """Write --cells and --mesh, print the mesh's quality; the summary's entries.

    --cells .vtu and .geojson and the OpenFOAM case of --mesh are written from the
    conforming mesh (``Diagram.mesh()``); a .ply goes through :func:`hcvt.io.write_cells`.
    With ``--mesh-boundary merged`` the case holds the merged mesh, and the quality
    figures are that mesh's (what checkMesh measures), beside ``merged_boundary``: the
    faces merged and the change of total volume against the exact mesh.
    """
    info: dict[str, Any] = {}
    suffix = Path(cells_path).suffix.lower() if cells_path else ""
    cells_from_mesh = suffix in (".vtu", ".geojson", ".json")
    if suffix == ".pvtu":  # written per part by the workers
        info["cells"] = str(cells_path)
    elif cells_path and not cells_from_mesh:
        hcvt.io.write_cells(diagram, cells_path)
        info["cells"] = str(cells_path)
    if not (cells_from_mesh or mesh_dir):
        return info
    mesh = diagram.mesh()  # once, for every file and the quality figures
    data = {"volume": diagram.volume, "G": diagram.G}
    start = time.perf_counter()
    if cells_path and cells_from_mesh:
        hcvt.write_mesh(mesh, cells_path, cell_data=data)
        info["cells"] = str(cells_path)
    measured = mesh
    if mesh_dir and mesh_boundary == "merged" and mesh.dim == 3:
        measured, report = merged_boundary(mesh, diagram.domain)
        exact_total = float(mesh.cell_geometry.volume.sum())
        info["merged_boundary"] = {
            "rounds": report.rounds,
            "faces_merged": report.merged_faces,
            "merged_faces": report.groups,
            "still_failing": len(report.failing),
            "volume_total_exact": exact_total,
            "volume_total_relative_change": float(
                measured.cell_geometry.volume.sum() / exact_total - 1.0
            ),
        }
        if len(report.failing):
            click.echo(f"warning: {len(report.failing)} boundary faces still fail after merging")
    if mesh_dir:
        hcvt.write_mesh(
            measured,
            mesh_dir,
            domain=diagram.domain,
            cell_data=data,
            boundary_faces="exact",  # merged above already
        )
        info["mesh"] = str(mesh_dir)
    info["write_seconds"] = time.perf_counter() - start
    quality = mesh_quality(measured).summary()
    info["mesh_quality"] = quality
    click.echo(
        f"mesh: {quality['cells']} cells, {quality['faces']} faces  "
        f"volume min {quality['volume_min']:.4g} max {quality['volume_max']:.4g} "
        f"total {quality['volume_total']:.12g}  non-orthogonality max "
        f"{quality['non_orthogonality_max']:.2f} average "
        f"{quality['non_orthogonality_average']:.2f} deg  skewness max "
        f"{quality['skewness_max']:.3f}  smallest cell / its neighbour "
        f"{quality['volume_ratio_min']:.3g}  (checkMesh's limits: "
        f"{quality['non_orthogonal_faces']} faces > 70 deg, {quality['skew_faces']} skewness > 4, "
        f"{quality['inverted_pyramids']} inverted pyramids, "
        f"{quality['high_aspect_cells']} cells aspect ratio > 1000)"
    )
    return info


def _voronoi(domain: Any, sites: Any, cells_pvtu: str | None = None, **kwargs: Any) -> Any:
    """``hcvt.voronoi``, or with ``cells_pvtu`` (and a client) partitioned.

    Its cells are then written as pieces by the workers first
    (:meth:`hcvt.distributed.PartitionedDiagram.write_cells`), and the diagram gathered.
    """
    if cells_pvtu is None:
        return hcvt.voronoi(domain, sites, **kwargs)

    per_part = kwargs.pop("sites_per_partition") or DEFAULT_SITES_PER_PARTITION
    parted = partitioned_voronoi(domain, sites, sites_per_partition=per_part, **kwargs)
    parted.write_cells(cells_pvtu)
    return parted.gather()


def _cvt(domain: Any, sites: Any, cells_pvtu: str | None = None, **kwargs: Any) -> Any:
    """``hcvt.cvt``, or with ``cells_pvtu`` (and a client) partitioned.

    The final diagram's cells are then written as pieces by the workers first (as
    :func:`_voronoi`), and the result gathered.
    """
    if cells_pvtu is None:
        return hcvt.cvt(domain, sites, **kwargs)

    per_part = kwargs.pop("sites_per_partition") or DEFAULT_SITES_PER_PARTITION
    result = partitioned_cvt(domain, sites, sites_per_partition=per_part, **kwargs)
    result.diagram.write_cells(cells_pvtu)
    return result.gather()


#: The methods ``run --scheduler`` partitions over dask.distributed workers.
PARTITIONED = ("voronoi", "lbfgs", "lloyd")


@contextlib.contextmanager
def _client(scheduler: str) -> Iterator[Any]:
    """A dask client of ``scheduler``, or of a LocalCluster (one worker process per core)."""
    dask_distributed = load("dask.distributed")
    Client, LocalCluster = dask_distributed.Client, dask_distributed.LocalCluster  # noqa: N806
    if scheduler == "local":
        workers = os.cpu_count() or 1
        with (
            LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster,
            Client(cluster) as client,
        ):
            yield client
    else:
        with Client(scheduler) as client:
            yield client


def _density(spec: str | None, sizing: str | None, dim: int) -> Any:
    """The density of ``--density`` or ``--sizing``, or None."""
    if spec is not None and sizing is not None:
        raise ValueError("give --density or --sizing, not both")
    if sizing is not None:
        return SizingField(_function(sizing))
    if spec is None:
        return None
    if ".py:" in spec:
        return _function(spec)
    return Polynomial.parse(spec, dim)


def _function(spec: str) -> Any:
    """The function NAME of ``FILE.py:NAME``, imported from the user's file."""
    path, _, name = spec.rpartition(":")
    if not path.endswith(".py") or not name:
        raise ValueError(f"expected FILE.py:NAME, got {spec!r}")
    module_spec = importlib.util.spec_from_file_location("hcvt_user_density", path)
    if module_spec is None or module_spec.loader is None or not Path(path).exists():
        raise FileNotFoundError(f"no Python file {path!r}")
    module = importlib.util.module_from_spec(module_spec)
    try:
        module_spec.loader.exec_module(module)
    except Exception as err:  # the user's file: any error it raises, one line, no traceback
        raise ValueError(f"cannot import {path}: {type(err).__name__}: {err}") from err
    function = getattr(module, name, None)
    if not callable(function):
        raise ValueError(f"{path} has no function {name!r}")
    return function


#: The last iterate's convergence measures, written to the summary (``hcvt.cvt`` docs).
CONVERGENCE_FIELDS = ("rms_gap", "max_gap", "grad_norm", "pinned")


def _volumes(spec: str, n: int, seed: int) -> np.ndarray:
    """--volumes: ``lognormal:SIGMA`` drawn from ``seed``, or a file of n values.

    The draws come from a child of ``seed``'s SeedSequence, so they are independent of the
    initial sites drawn from ``seed`` itself.
    """
    if spec.startswith("lognormal:"):
        try:
            sigma = float(spec.removeprefix("lognormal:"))
        except ValueError:
            raise click.UsageError(
                f"--volumes lognormal:SIGMA needs a number, got {spec!r}"
            ) from None
        if not (np.isfinite(sigma) and sigma >= 0):
            raise click.UsageError(f"--volumes lognormal:SIGMA needs SIGMA >= 0, got {sigma}")
        rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
        return rng.lognormal(0.0, sigma, n)
    path = Path(spec)
    if not path.exists():
        raise click.UsageError(f"--volumes: {spec!r} is neither lognormal:SIGMA nor a file")
    values = np.load(path) if path.suffix.lower() == ".npy" else np.loadtxt(path, ndmin=1)
    values = np.asarray(values, dtype=np.float64).ravel()
    if values.shape != (n,):
        raise click.UsageError(f"--volumes {spec}: {values.size} values for {n} sites")
    return values


def _scalar(value: Any) -> float | int:
    """A numpy scalar as the plain Python number JSON takes."""
    return value.item() if hasattr(value, "item") else value


def _write_sites(path: Path, sites: np.ndarray) -> None:
    if path.suffix == ".npy":
        np.save(path, sites)
    elif path.suffix == ".csv":
        header = ",".join("xyz"[: sites.shape[1]])
        np.savetxt(path, sites, delimiter=",", header=header, comments="")
    else:
        raise ValueError(f"--out must end in .npy or .csv, got {path.name}")


def _plot(diagram: Any, path: str) -> None:

    if diagram.domain.dim == 2:
        ax = pictures.plot_cells(diagram, show_defects=True)
    else:
        ax = pictures.plot_cut(diagram)
    pictures.save(ax, path)


@main.command()
@click.argument("summary", type=click.Path(exists=True, dir_okay=False))
@click.option("--plot", type=click.Path(dir_okay=False), required=True, help="PNG to write.")
def show(summary: str, plot: str) -> None:
    """Picture of a saved result: a summary JSON written by ``hcvt run --summary``."""
    info = json.loads(Path(summary).read_text())
    if "sites" not in info:
        raise ValueError(f"{summary} has no sites file; run with --out and --summary")
    sites_path = Path(info["sites"])
    try:
        sites = (
            np.load(sites_path)
            if sites_path.suffix == ".npy"
            else np.loadtxt(sites_path, delimiter=",", skiprows=1)
        )
    except EOFError as err:  # np.load of an empty file; click would say only "Aborted!"
        raise ValueError(f"{sites_path}: cannot read sites ({err})") from err
    domain = _load(info["input"], False, info.get("radius", 1.0), region=info.get("region"))
    _check_outputs(domain, None, plot)
    _plot(hcvt.voronoi(domain, sites), plot)


@main.command()
@click.argument("experiment")
@click.option("--runs", type=int, default=10, show_default=True, help="Seeds per random case.")
@click.option("--quick", is_flag=True, help="Reduced sizes: every experiment in minutes.")
@click.option("--scheduler", default=None, help="dask scheduler address (default: local).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="results")
def reproduce(experiment: str, runs: int, quick: bool, scheduler: str | None, out_dir: str) -> None:
    """Reproduce a table or figure of the paper (EXPERIMENT: table2 … table8, fig5 … fig12, all).

    Writes OUT/EXPERIMENT.md (ours beside the paper's), OUT/EXPERIMENT.csv and the figures.
    """
    if runs < 1:
        raise ValueError(f"--runs must be at least 1, got {runs}")
    with load("rich.progress").Progress(transient=True) as bar:
        tasks: dict[str, Any] = {}

        def step(name: str, done: int, total: int) -> None:
            if name not in tasks:
                tasks[name] = bar.add_task(name, total=total)
            bar.update(tasks[name], completed=done)

        report = run_experiment(
            experiment, runs=runs, quick=quick, scheduler=scheduler, out=out_dir, progress=step
        )
    click.echo(report.read_text())
    click.echo(f"written: {report}")
