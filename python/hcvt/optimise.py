"""Centroidal Voronoi tessellations from given sites: L-BFGS, Newton or Lloyd (DESIGN §4).

The whole iteration runs in the Rust core (``hcvt-core/src/optimise``), one exact clipped
diagram per energy evaluation, with the GIL released; Python is called back once per
iteration only to check for Ctrl-C and, if asked, to run ``callback`` or show progress.

Stopping rule: the paper's ``‖g‖/‖X‖ < tol`` (§5.4, after Quinn et al. 2012), evaluated in
normalised coordinates ``y = (x - o)/s`` with ``o`` the centre of the domain's bounding box
and ``s`` its longest side, so that the rule depends neither on the unit nor on where the
domain sits: ``‖g‖/‖X‖ = ‖∇E(x)‖ / (s^d ‖x - o‖)``. The history also holds the scale-free
gap ``max_i |x_i - c_i| / h`` with ``h = (V/n)^(1/d)``.

Sites stay inside the domain: a step is shortened site by site until it ends inside. In a
non-convex domain the centroid of a cell at a notch can lie outside; its site then ends
pinned on the boundary, where its gradient cannot vanish. Such sites (centroid outside, and
not even 2^-20 of the way towards it inside) are counted in ``history["pinned"]`` and left
out of the stopping rule and the gap; Newton's steps leave them where they are.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt import _core
from hcvt.diagram import Diagram, as_sites
from hcvt.domain import Domain

METHODS = ("lbfgs", "lloyd", "newton")


@dataclass
class CVTResult:
    """The outcome of :func:`cvt`.

    Attributes
    ----------
    sites : ndarray, shape (n, d)
        Final sites, in the domain's unit L.
    diagram : Diagram
        Clipped Voronoi diagram of the final sites.
    history : dict of str to ndarray
        One entry per iterate, the initial sites first (length ``iterations + 1``):
        ``energy`` (L^(d+2)), ``mean_G``, ``grad_norm`` (``‖g‖/‖X‖``, normalised),
        ``gap`` (``max |x_i - c_i| / h``), ``pinned`` (sites held on the boundary with
        their centroid outside, left out of ``grad_norm`` and ``gap``; module docs),
        ``seconds`` (since the start),
        ``evaluations`` (diagrams so far), ``step`` (``"start"``, ``"lbfgs"``, ``"newton"``,
        ``"lloyd"`` -- also the fallback when a step search stalls in round-off --
        or ``"reseed"``).
    converged : bool
        Whether ``grad_norm < tol`` was reached.
    stop_reason : str
        ``"converged"``, ``"max_iter"`` or ``"interrupted"`` (the callback asked).
    iterations : int
        Steps taken.
    evaluations : int
        Diagrams computed (one per energy-and-gradient evaluation).
    seconds : float
        Wall time of the optimisation.
    """

    sites: NDArray[np.float64]
    diagram: Diagram
    history: dict[str, NDArray[Any]] = field(repr=False)
    converged: bool
    stop_reason: str
    iterations: int
    evaluations: int
    seconds: float

    @property
    def mean_G(self) -> float:  # noqa: N802 (the paper's G)
        """Mean G of the final diagram (paper eq. 3)."""
        return self.diagram.mean_G

    @property
    def energy(self) -> float:
        """CVT energy of the final sites, L^(d+2)."""
        return self.diagram.energy


def cvt(
    domain: Domain,
    sites: ArrayLike,
    method: str = "lbfgs",
    *,
    tol: float = 1e-10,
    max_iter: int = 10_000,
    memory: int = 7,
    callback: Callable[[dict[str, Any]], Any] | None = None,
    progress: bool = False,
) -> CVTResult:
    """Move ``sites`` to a centroidal Voronoi tessellation of ``domain``.

    Parameters
    ----------
    domain : Domain
        Polygon (d = 2) or solid (d = 3); length unit L.
    sites : array_like of float, shape (n, d)
        Initial sites: finite, distinct, inside the domain. Not modified.
    method : {"lbfgs", "newton", "lloyd"}
        L-BFGS (memory ``memory``, strong-Wolfe line search, preconditioned so that its
        first step is a Lloyd step; the paper's method), Newton (the exact Hessian from
        the same diagram, truncated conjugate gradients in a trust region; usually 2-4x
        fewer diagrams, see ``hcvt-core/src/optimise/newton.rs``; the Hessian takes about
        0.2 kB per site in 2D and 1.2 kB in 3D on top of the diagram) or Lloyd's
        ``x_i <- c_i``.
    tol : float
        Stop when ``‖g‖/‖X‖ < tol`` in normalised coordinates (module docs; paper 1e-10).
    max_iter : int
        Stop after this many iterations.
    memory : int
        L-BFGS correction pairs kept.
    callback : callable, optional
        ``callback(info)`` after every iterate (the initial sites first), ``info`` a dict
        with the history fields of that iterate and ``sites`` (n, d). Returning a true
        value stops the run (``stop_reason == "interrupted"``).
    progress : bool
        Show a progress bar (rich) towards ``tol``.

    Returns
    -------
    CVTResult
        ``sites``, ``diagram``, ``history``, ``converged``, ``stop_reason``,
        ``iterations``, ``evaluations``, ``seconds``.

    Raises
    ------
    ValueError
        Unknown method, negative tol, bad shape.
    InvalidSitesError
        Sites outside the domain, coinciding or non-finite; the message names the row.

    Examples
    --------
    Four sites in the unit square converge to the 2 x 2 grid of squares, G = 1/12.

    >>> import hcvt
    >>> square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    >>> res = hcvt.cvt(square, [[0.2, 0.3], [0.7, 0.2], [0.3, 0.6], [0.8, 0.9]])
    >>> res.converged, res.stop_reason
    (True, 'converged')
    >>> res.sites.round(6)
    array([[0.25, 0.25],
           [0.75, 0.25],
           [0.25, 0.75],
           [0.75, 0.75]])
    >>> round(res.mean_G, 6)
    0.083333
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if not tol >= 0:
        raise ValueError(f"tol must be a number >= 0, got {tol!r}")
    if max_iter < 0 or memory < 1:
        raise ValueError(f"need max_iter >= 0 and memory >= 1, got {max_iter}, {memory}")
    points = as_sites(sites, domain.dim)
    run = getattr(_core, f"cvt_{domain.dim}d", None)
    if run is None:
        raise NotImplementedError(f"no CVT for dimension {domain.dim} in this build")
    bar = _Progress(tol) if progress else None
    observe = _chain(callback, bar)
    try:
        out = run(
            domain._core,
            points,
            method=method,
            tol=float(tol),
            max_iter=int(max_iter),
            memory=int(memory),
            callback=observe,
        )
    finally:
        if bar is not None:
            bar.close()
    history = {key: np.asarray(value) for key, value in out["history"].items()}
    sites_out = out["sites"]
    return CVTResult(
        sites=sites_out,
        diagram=Diagram(domain, sites_out, out["diagram"]),
        history=history,
        converged=out["stop_reason"] == "converged",
        stop_reason=out["stop_reason"],
        iterations=int(out["iterations"]),
        evaluations=int(out["evaluations"]),
        seconds=float(history["seconds"][-1]),
    )


def _chain(
    callback: Callable[[dict[str, Any]], Any] | None, bar: _Progress | None
) -> Callable[[dict[str, Any]], bool] | None:
    """One observer for the core: the progress bar, then the user's callback."""
    if callback is None and bar is None:
        return None

    def observe(info: dict[str, Any]) -> bool:
        if bar is not None:
            bar.update(info)
        return bool(callback(info)) if callback is not None else False

    return observe


class _Progress:
    """A rich progress bar whose completion is ``log(g0/g) / log(g0/tol)``."""

    def __init__(self, tol: float) -> None:
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        self._tol = max(tol, 1e-300)
        self._start: float | None = None
        self._progress = Progress(
            TextColumn("CVT"),
            BarColumn(),
            TextColumn("{task.fields[status]}"),
            TimeElapsedColumn(),
            transient=False,
        )
        self._task = self._progress.add_task("cvt", total=1.0, status="")
        self._progress.start()

    def update(self, info: dict[str, Any]) -> None:
        g = max(float(info["grad_norm"]), 1e-300)
        if self._start is None:
            self._start = g
        span = math.log(self._start / self._tol) if self._start > self._tol else 1.0
        done = min(max(math.log(self._start / g) / span, 0.0), 1.0) if span > 0 else 1.0
        status = (
            f"|g|/|X| {g:.2e}  gap {info['gap']:.2e}  mean G {info['mean_G']:.6f}  "
            f"diagrams {info['evaluations']}"
        )
        self._progress.update(self._task, completed=done, status=status)

    def close(self) -> None:
        self._progress.stop()


__all__ = ["CVTResult", "cvt"]
