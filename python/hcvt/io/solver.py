"""Does a real solver converge on a written case? OpenFOAM's ``laplacianFoam`` on a linear field.

A linear field ``T = a·x + b`` solves Laplace's equation exactly, and the finite-volume
Laplacian with Gauss linear, corrected (non-orthogonal correction by the gradient) is
exact for it up to the face-interpolation and gradient errors of the mesh: a good mesh
reproduces ``T`` at its cell centres to the discretisation error, a bad one (faces far
from orthogonal, tiny cells beside large ones) does not, or the non-orthogonal
correctors do not converge at all. :func:`laplace_check` sets up and runs that test on a
case written by :func:`hcvt.export.write_openfoam`, on a scratch copy (the case is read,
never changed):

1. ``postProcess -func writeCellCentres`` writes OpenFOAM's own cell centres and boundary
   face centres (for a merged, non-planar face, the centre of OpenFOAM's fan);
2. ``0/T`` is the linear field at the boundary face centres, ``fixedValue`` on every wall
   patch (``empty`` on the ``frontAndBack`` of an extruded 2D mesh), ``T`` spanning
   ``[-1, 1]`` over the face centres along the direction ``(1, 2, 3)`` (``(1, 2, 0)`` in
   2D); in a periodic box (``cyclic`` patches) that direction with its components along
   the periods (the patches' ``separationVector``) removed, the field periodic;
3. ``laplacianFoam`` runs steady (``ddtSchemes steadyState``): ``steps`` steps of
   ``correctors`` non-orthogonal correctors each, every solve by PCG/DIC to an absolute
   tolerance of 1e-15 (so that the next solve's *initial* residual measures what the
   non-orthogonal correction still changes);
4. the last step's ``T`` is compared with the exact field at the cell centres.

A box periodic along every axis has no walls to hold a linear field (it would not be
periodic): there the check is transient instead, a decaying Fourier mode. ``T`` starts as
``sin(2π b·x)`` with ``b = Σ_a e_a / L_a`` over the periods ``L_a`` (the largest
component of the cyclic patches' ``separationVector`` along each axis: the axis-aligned
boxes :class:`hcvt.Domain` writes), which is periodic; backward Euler with the diffusivity
chosen so that ``λ Δt = 1/4`` (``λ = 4π²|b|²``) multiplies the exact mode by
``1/(1 + λ Δt)`` per step, so after ``steps`` steps ``T`` must be ``1.25^-steps`` times the
initial mode at the cell centres, to the mesh's discretisation error; the non-orthogonal
correctors must converge within each step as in the steady check.

The case's verdict is :class:`LaplaceCheck`: the last solve's initial residual (OpenFOAM's
normalised residual), converged when it is below ``tol`` (1e-10), and the RMS and largest
error of ``T``.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hcvt.errors import InvalidMeshError
from hcvt.io.openfoam import foam_header

#: Debian's and Ubuntu's OpenFOAM (``apt install openfoam``), used when ``WM_PROJECT_DIR``
#: is not set.
DEFAULT_PROJECT_DIR = "/usr/share/openfoam"

#: The last solve's initial residual below which :func:`laplace_check` calls it converged.
RESIDUAL_TOL = 1e-10

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf)"


class OpenFOAMError(RuntimeError):
    """An OpenFOAM program is missing, or it failed (its message is quoted)."""


@dataclass(frozen=True)
class LaplaceCheck:
    """What :func:`laplace_check` measured (``T`` spans ``[-1, 1]``, or a mode of amplitude 1)."""

    converged: bool
    """Whether the last solve's initial residual is below the tolerance."""
    residual: float
    """The last solve's initial residual (OpenFOAM's normalised residual)."""
    residuals: NDArray[np.float64]
    """Shape (solves,): the initial residual of every solve, in order."""
    rms_error: float
    """RMS over the cells of ``T - T_exact`` at OpenFOAM's cell centres (inf if not finite)."""
    max_error: float
    """Largest ``|T - T_exact|`` over the cells (inf if not finite)."""
    cells: int
    """Cells of the mesh."""
    field: str = "linear"
    """``"linear"`` (the steady linear field), or ``"decaying mode"`` in a box periodic
    along every axis (module docs)."""

    def summary(self) -> dict[str, float | int | bool | str]:
        """The figures as plain numbers, for JSON."""
        return {
            "converged": self.converged,
            "residual": self.residual,
            "solves": len(self.residuals),
            "rms_error": self.rms_error,
            "max_error": self.max_error,
            "cells": self.cells,
            "field": self.field,
        }


def laplace_check(
    case: str | Path,
    *,
    steps: int = 4,
    correctors: int = 10,
    sn_grad: str = "corrected",
    tol: float = RESIDUAL_TOL,
    workdir: str | Path | None = None,
) -> LaplaceCheck:
    """Run ``laplacianFoam`` on a known solution over the mesh of ``case`` (module docs).

    A linear field, or in a box periodic along every axis a decaying Fourier mode.

    Parameters
    ----------
    case : str or Path
        An OpenFOAM case with ``constant/polyMesh`` (as :func:`hcvt.write_mesh` writes it);
        only read.
    steps, correctors : int
        Steady steps, and non-orthogonal correctors per step: ``steps * (correctors + 1)``
        solves in all.
    sn_grad : str
        The snGrad and Laplacian correction, OpenFOAM's syntax: ``"corrected"`` (exact for
        a linear field), ``"limited corrected 0.5"``, ``"uncorrected"``, ...
    tol : float
        Converged when the last solve's initial residual is below this.
    workdir : str or Path, optional
        Where to run (created; its ``constant/polyMesh`` links to the case's), kept
        afterwards. Default: a temporary directory, removed.

    Returns
    -------
    LaplaceCheck

    Raises
    ------
    InvalidMeshError
        ``case`` has no ``constant/polyMesh/boundary``.
    OpenFOAMError
        ``postProcess`` or ``laplacianFoam`` is not on the PATH, or one of them failed.
    """
    case = Path(case)
    boundary_file = case / "constant" / "polyMesh" / "boundary"
    if not boundary_file.is_file():
        raise InvalidMeshError(f"{case} is no OpenFOAM case: {boundary_file} is missing")
    if steps < 1 or correctors < 0:
        raise ValueError(f"steps must be >= 1 and correctors >= 0, got {steps}, {correctors}")
    patches = _patch_types(boundary_file.read_text())
    if workdir is not None:
        root = Path(workdir)
        return _run(case, root, patches, steps, correctors, sn_grad, tol)
    with tempfile.TemporaryDirectory(prefix="hcvt-laplace-") as tmp:
        return _run(case, Path(tmp), patches, steps, correctors, sn_grad, tol)


def _run(
    case: Path,
    root: Path,
    patches: dict[str, str],
    steps: int,
    correctors: int,
    sn_grad: str,
    tol: float,
) -> LaplaceCheck:
    constant = root / "constant"
    constant.mkdir(parents=True, exist_ok=True)
    link = constant / "polyMesh"
    if link.is_symlink() or link.exists():
        if link.is_symlink() or link.is_file():
            link.unlink()
        else:
            shutil.rmtree(link)
    link.symlink_to((case / "constant" / "polyMesh").resolve(), target_is_directory=True)
    system = root / "system"
    system.mkdir(exist_ok=True)
    for stale in root.iterdir():  # time directories of an earlier run in workdir
        if stale.is_dir() and re.fullmatch(r"\d+(\.\d+)?", stale.name) and stale.name != "0":
            shutil.rmtree(stale)
    (system / "controlDict").write_text(
        foam_header("dictionary", "controlDict", location="system")
        + _CONTROL_DICT.format(end=steps)
    )
    _write_schemes(root, sn_grad, transient=False)  # postProcess reads them
    (system / "fvSolution").write_text(
        foam_header("dictionary", "fvSolution", location="system")
        + _FV_SOLUTION.format(correctors=correctors)
    )
    (root / "0").mkdir(exist_ok=True)
    _foam(["postProcess", "-func", "writeCellCentres", "-time", "0"], root)
    centres = (root / "0" / "C").read_text()
    cell_centre = _vectors(_internal(centres))
    face_centre = {
        name: _vectors(_patch_value(centres, name))
        for name, kind in patches.items()
        if kind not in ("empty", "cyclic")
    }
    two_d = any(kind == "empty" for kind in patches.values())
    direction = np.array([1.0, 2.0, 0.0 if two_d else 3.0])
    # Periodic (cyclic) axes: the field is linear across the others only.
    boundary = (case / "constant" / "polyMesh" / "boundary").read_text()
    vector = rf"separationVector\s*\(\s*({_NUMBER})\s+({_NUMBER})\s+({_NUMBER})"
    shifts = np.array(re.findall(vector, boundary), dtype=np.float64).reshape(-1, 3)
    if len(shifts):
        _, sigma, basis = np.linalg.svd(shifts)
        span = basis[: int(np.sum(sigma > 1e-12 * sigma[0]))]
        direction -= span.T @ (span @ direction)
    if not face_centre:  # periodic along every axis: no wall to hold a linear field
        return _decaying_mode(root, patches, shifts, cell_centre, steps, sn_grad, tol)
    _write_diffusivity(root, 1.0)
    along = {name: c @ direction for name, c in face_centre.items()}
    values = np.concatenate([*along.values(), cell_centre @ direction])
    lo, hi = float(values.min()), float(values.max())

    def exact(projection: NDArray[np.float64]) -> NDArray[np.float64]:
        return 2.0 * (projection - lo) / (hi - lo) - 1.0

    _write_t(root / "0" / "T", patches, {name: exact(a) for name, a in along.items()})
    residuals, t = _solve(root, steps, len(cell_centre))
    return _verdict(residuals, t - exact(cell_centre @ direction), tol, "linear")


def _decaying_mode(
    root: Path,
    patches: dict[str, str],
    shifts: NDArray[np.float64],
    cell_centre: NDArray[np.float64],
    steps: int,
    sn_grad: str,
    tol: float,
) -> LaplaceCheck:
    """The transient check of a box periodic along every axis (module docs)."""
    periods = np.abs(shifts).max(axis=0)
    b = np.divide(1.0, periods, out=np.zeros(3), where=periods > 0)
    rate = 4.0 * np.pi**2 * float(b @ b)  # λ of the mode for a diffusivity of 1
    _write_schemes(root, sn_grad, transient=True)
    _write_diffusivity(root, 0.25 / rate)
    mode = np.sin(2.0 * np.pi * (cell_centre @ b))
    _write_t(root / "0" / "T", patches, {}, internal=mode)
    residuals, t = _solve(root, steps, len(cell_centre))
    return _verdict(residuals, t - mode * 1.25**-steps, tol, "decaying mode")


def _write_schemes(root: Path, sn_grad: str, *, transient: bool) -> None:
    """The case's ``system/fvSchemes``: backward Euler in time, or steady."""
    (root / "system" / "fvSchemes").write_text(
        foam_header("dictionary", "fvSchemes", location="system")
        + _FV_SCHEMES.format(sn_grad=sn_grad, ddt="Euler" if transient else "steadyState")
    )


def _write_diffusivity(root: Path, diffusivity: float) -> None:
    """The case's ``constant/transportProperties``: ``DT`` in m²/s."""
    (root / "constant" / "transportProperties").write_text(
        foam_header("dictionary", "transportProperties", location="constant")
        + f"DT              DT [0 2 -1 0 0 0 0] {diffusivity!r};\n"
    )


def _solve(root: Path, steps: int, cells: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Run laplacianFoam: every solve's initial residual, and ``T`` after ``steps`` steps."""
    log = _foam(["laplacianFoam"], root)
    residuals = np.array(
        [float(r) for r in re.findall(rf"Solving for T, Initial residual = ({_NUMBER})", log)]
    )
    if len(residuals) == 0:
        raise OpenFOAMError(f"laplacianFoam solved nothing in {root}:\n{log[-2000:]}")
    return residuals, _scalars(_internal((root / str(steps) / "T").read_text()), cells)


def _verdict(
    residuals: NDArray[np.float64], error: NDArray[np.float64], tol: float, field: str
) -> LaplaceCheck:
    finite = bool(np.isfinite(error).all())
    residual = float(residuals[-1])
    return LaplaceCheck(
        converged=finite and residual < tol,
        residual=residual,
        residuals=residuals,
        rms_error=float(np.sqrt(np.mean(error**2))) if finite else float("inf"),
        max_error=float(np.abs(error).max()) if finite else float("inf"),
        cells=len(error),
        field=field,
    )


def _foam(command: list[str], root: Path) -> str:
    """Run an OpenFOAM program on the case ``root``; its output, or OpenFOAMError."""
    if shutil.which(command[0]) is None:
        raise OpenFOAMError(
            f"{command[0]} is not on the PATH: OpenFOAM is needed (Debian/Ubuntu: apt "
            "install openfoam; or source its etc/bashrc)"
        )
    env = {**os.environ}
    env.setdefault("WM_PROJECT_DIR", DEFAULT_PROJECT_DIR)
    done = subprocess.run(
        [*command, "-case", str(root)], capture_output=True, text=True, env=env, check=False
    )
    if done.returncode != 0 or "FOAM FATAL" in done.stdout + done.stderr:
        message = done.stderr.strip() or done.stdout.strip()
        raise OpenFOAMError(
            f"{' '.join(command)} failed on {root} (exit {done.returncode}):\n{message[-2000:]}"
        )
    return done.stdout


# ----------------------------------------------------------------------------- parsing
def _patch_types(boundary: str) -> dict[str, str]:
    """Patch name -> type, from a polyBoundaryMesh file, in order."""
    body = boundary[boundary.index("}") + 1 :]  # past the FoamFile header
    return dict(re.findall(r"(\w+)\s*\{[^}]*?\btype\s+(\w+)\s*;", body))


def _internal(field: str) -> str:
    found = re.search(r"internalField\s+([^;]*);", field)
    if found is None:
        raise OpenFOAMError("a field file written by OpenFOAM has no internalField")
    return found.group(1)


def _patch_value(field: str, patch: str) -> str:
    found = re.search(rf"\b{re.escape(patch)}\s*\{{[^}}]*?\bvalue\s+([^;]*);", field)
    if found is None:
        raise OpenFOAMError(f"a field file written by OpenFOAM has no value on patch {patch}")
    return found.group(1)


def _numbers(entry: str) -> tuple[bool, NDArray[np.float64]]:
    """(uniform, numbers) of an entry ``uniform x``, ``nonuniform List<..> N (...)``."""
    entry = entry.strip()
    uniform = entry.startswith("uniform")
    if not uniform:
        entry = re.sub(r"^nonuniform\s+List<\w+>\s*\d+", "", entry)
    words = entry.removeprefix("uniform").replace("(", " ").replace(")", " ").split()
    return uniform, np.array(words, dtype=np.float64)


def _vectors(entry: str) -> NDArray[np.float64]:
    uniform, numbers = _numbers(entry)
    return numbers.reshape(-1, 3)


def _scalars(entry: str, n: int) -> NDArray[np.float64]:
    uniform, numbers = _numbers(entry)
    return np.full(n, numbers[0]) if uniform else numbers


# ----------------------------------------------------------------------------- files
def _write_t(
    path: Path,
    patches: dict[str, str],
    values: dict[str, NDArray[np.float64]],
    internal: NDArray[np.float64] | None = None,
) -> None:
    """``0/T``: fixed ``values`` on the wall patches, ``internal`` in the cells (else 0)."""
    entries = []
    for name, kind in patches.items():
        if kind in ("empty", "cyclic"):
            entries.append(f"    {name}\n    {{\n        type            {kind};\n    }}\n")
            continue
        entries.append(
            f"    {name}\n    {{\n        type            fixedValue;\n"
            f"        value           {_field_entry(values[name])};\n    }}\n"
        )
    path.write_text(
        foam_header("volScalarField", "T", location="0")
        + "dimensions      [0 0 0 0 0 0 0];\n\ninternalField   "
        + _field_entry(internal)
        + ";\n\n"
        + "boundaryField\n{\n"
        + "".join(entries)
        + "}\n"
    )


def _field_entry(values: NDArray[np.float64] | None) -> str:
    if values is None:
        return "uniform 0"
    words = "\n".join(np.asarray(values, dtype=np.float64).astype(str).tolist())
    return f"nonuniform List<scalar>\n{len(values)}\n(\n{words}\n)\n"


_CONTROL_DICT = """application     laplacianFoam;
startFrom       startTime;
startTime       0;
stopAt          endTime;
endTime         {end};
deltaT          1;
writeControl    timeStep;
writeInterval   {end};
purgeWrite      0;
writeFormat     ascii;
writePrecision  17;
writeCompression off;
timeFormat      general;
timePrecision   6;
runTimeModifiable false;
"""

_FV_SCHEMES = """ddtSchemes {{ default {ddt}; }}
gradSchemes {{ default Gauss linear; }}
divSchemes {{ default none; }}
laplacianSchemes {{ default Gauss linear {sn_grad}; }}
interpolationSchemes {{ default linear; }}
snGradSchemes {{ default {sn_grad}; }}
"""

_FV_SOLUTION = """solvers
{{
    T
    {{
        solver          PCG;
        preconditioner  DIC;
        tolerance       1e-15;
        relTol          0;
        maxIter         5000;
    }}
}}
SIMPLE {{ nNonOrthogonalCorrectors {correctors}; }}
"""
