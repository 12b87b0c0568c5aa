"""Centroidal Voronoi tessellations from given sites: L-BFGS, Newton or Lloyd (DESIGN §4).

The whole iteration runs in the Rust core (``hcvt-core/src/optimise``), one exact clipped
diagram per energy evaluation, with the GIL released; Python is called back once per
iteration only to check for Ctrl-C and, if asked, to run ``callback`` or show progress.

Stopping rules (``rule=``, DESIGN §7), both reported at every iterate:

- ``"gap"`` (the default): the scale-free gap ``r_i = |x_i - c_i| / h_i`` of each site to
  its centroid, ``h_i = V_i^(1/d)`` the size of its own cell; stop when ``RMS(r) < tol``
  (default ``1e-7``, :data:`GAP_TOL`), with ``max(r)`` reported beside it. It means the same
  for every unit, position, shape and number of sites: at the default, mean G is settled to
  8 digits and no site is farther than about 1e-5 spacings from its centroid
  (``docs/results.md``, "Stopping rule").
- ``"paper"``: the paper's rule to the letter, ``‖g‖/‖X‖ < tol`` (default ``1e-10``,
  :data:`PAPER_TOL`) with the gradient ``g_i = 2 m_i (x_i - c_i)`` and the sites ``X`` in the
  input coordinates (§5.4, after Quinn et al. 2012). It changes with the unit and with a
  translation (on Staten Island in State Plane feet ``‖X‖`` is the offset), so it is the rule
  for figures set beside the paper's, in the paper's coordinates, and little else.

Sites stay inside the domain: a step is shortened site by site until it ends inside. In a
non-convex domain the centroid of a cell at a notch can lie outside; its site then ends
pinned on the boundary, where its gradient cannot vanish. Such sites (centroid outside, and
not even 2^-20 of the way towards it inside) are counted in ``history["pinned"]`` and left
out of both rules and the gaps; Newton's steps leave them where they are.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt import _core
from hcvt.density import DEFAULT_QUADRATURE_DEGREE, DensityLike, core_arguments
from hcvt.diagram import Diagram, as_sites
from hcvt.domain import Domain

RULES = ("gap", "paper")
#: Default tolerance of ``rule="gap"`` on the RMS of ``|x_i - c_i| / V_i^(1/d)``.
GAP_TOL = 1e-7
#: Default tolerance of ``rule="paper"`` on ``‖g‖/‖X‖`` in input coordinates (the paper's).
PAPER_TOL = 1e-10


def default_tol(rule: str) -> float:
    """The tolerance used for ``rule`` when none is given: 1e-7 (gap) or 1e-10 (paper)."""
    return float(_core.check_settings("lbfgs", rule, None, 0, 1))


def check_rule(rule: str) -> None:
    """Raise ``ValueError`` unless ``rule`` is ``"gap"`` or ``"paper"`` (the core's check)."""
    default_tol(rule)


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
        ``energy`` (L^(d+2)), ``mean_G``, ``rms_gap`` and ``max_gap`` (RMS and largest
        ``|x_i - c_i| / V_i^(1/d)``, dimensionless), ``grad_norm`` (the paper's
        ``‖g‖/‖X‖`` in input coordinates, L^d), ``pinned`` (sites held on the boundary with
        their centroid outside, left out of the gaps and ``grad_norm``; module docs),
        ``seconds`` (since the start),
        ``evaluations`` (diagrams so far), ``step`` (``"start"``, ``"lbfgs"``, ``"newton"``,
        ``"lloyd"`` -- also the fallback when a step search stalls in round-off --
        or ``"reseed"``).
    rule : str
        The stopping rule, ``"gap"`` or ``"paper"``.
    tol : float
        Its tolerance.
    converged : bool
        Whether the rule's value (``rms_gap`` or ``grad_norm``) fell below ``tol``.
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
    rule: str
    tol: float
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
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 10_000,
    memory: int = 7,
    callback: Callable[[dict[str, Any]], Any] | None = None,
    progress: bool = False,
    client: Any = None,
    sites_per_partition: int | None = None,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
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
        the same diagram, truncated conjugate gradients in a trust region; 3-5x fewer
        diagrams from random sites, see ``hcvt-core/src/optimise/newton.rs``; the Hessian
        takes about 0.2 kB per site in 2D and 1.2 kB in 3D on top of the diagram) or Lloyd's
        ``x_i <- c_i``.
    rule : {"gap", "paper"}
        Stop when the RMS over the sites of ``|x_i - c_i| / V_i^(1/d)`` is below ``tol``
        (``"gap"``, scale-free), or when ``‖g‖/‖X‖ < tol`` in the input coordinates
        (``"paper"``, the paper's rule to the letter); module docs.
    tol : float, optional
        The rule's tolerance; default 1e-7 for ``"gap"``, the paper's 1e-10 for ``"paper"``.
    max_iter : int
        Stop after this many iterations.
    memory : int
        L-BFGS correction pairs kept.
    callback : callable, optional
        ``callback(info)`` after every iterate (the initial sites first), ``info`` a dict
        with the history fields of that iterate and ``sites`` (n, d). Returning a true
        value, or raising ``StopIteration`` as with scipy.optimize, stops the run
        (``stop_reason == "interrupted"``).
    progress : bool
        Show a progress bar (rich) of the rule's value towards ``tol``.
    client : dask.distributed.Client, optional
        Run on its workers, the sites and their state split into spatial parts of at most
        ``sites_per_partition`` sites (default 200,000) that stay there between iterations
        (:mod:`hcvt.distributed`; ``"lbfgs"`` and ``"lloyd"`` only; the callback's info
        then has no ``sites``). Lloyd is bitwise the single-process run; L-BFGS is bitwise
        the same for any number of workers, not the single-process iterates; with a
        ``density`` too.
    sites_per_partition : int, optional
        With ``client``: the most sites one part holds.
    density : Polynomial, SizingField or callable, optional
        A density ρ > 0 (:mod:`hcvt.density`): the energy becomes ``Σ ∫ ρ |x - x_i|²``,
        Lloyd moves each site to its ρ-weighted centroid and L-BFGS follows the ρ-weighted
        gradient; both rules apply unchanged (``h_i`` stays the geometric ``V_i^(1/d)``).
        Newton's Hessian weighs its face terms by ρ on each face, exactly for a
        :class:`~hcvt.density.Polynomial`; with a callable Newton is not offered
        (InvalidDensityError). A callable is called once per diagram, with the GIL.
    quadrature_degree : int, default 4
        Degree (1 to 5) of the simplex rule that samples a callable density.

    Returns
    -------
    CVTResult
        ``sites``, ``diagram``, ``history``, ``rule``, ``tol``, ``converged``,
        ``stop_reason``, ``iterations``, ``evaluations``, ``seconds``.

    Raises
    ------
    ValueError
        Unknown method or rule, negative tol, bad shape.
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
    # The core checks the settings for both drivers (and tells the rule's default tol).
    tol = _core.check_settings(method, rule, tol, max_iter, memory)
    if client is not None:
        from hcvt.distributed import DEFAULT_SITES_PER_PARTITION, partitioned_cvt

        return partitioned_cvt(
            domain,
            sites,
            method,
            client,
            rule=rule,
            tol=tol,
            max_iter=max_iter,
            memory=memory,
            callback=callback,
            progress=progress,
            sites_per_partition=sites_per_partition or DEFAULT_SITES_PER_PARTITION,
            density=density,
            quadrature_degree=quadrature_degree,
        ).gather()
    points = as_sites(sites, domain.dim)
    weighted = core_arguments(density, domain.dim, quadrature_degree)
    run = getattr(_core, f"cvt_{domain.dim}d", None)
    if run is None:
        raise NotImplementedError(f"no CVT for dimension {domain.dim} in this build")
    bar = _Progress(rule, tol) if progress else None
    observe = _chain(callback, bar)
    try:
        out = run(
            domain._core,
            points,
            method=method,
            rule=rule,
            tol=float(tol),
            max_iter=int(max_iter),
            memory=int(memory),
            callback=observe,
            **weighted,
        )
    finally:
        if bar is not None:
            bar.close()
    history = {key: np.asarray(value) for key, value in out["history"].items()}
    sites_out = out["sites"]
    return CVTResult(
        sites=sites_out,
        diagram=Diagram(domain, sites_out, out["diagram"], density),
        history=history,
        rule=rule,
        tol=float(tol),
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
        if callback is None:
            return False
        try:
            return bool(callback(info))
        except StopIteration:  # scipy.optimize's way to stop from a callback
            return True

    return observe


#: The history field that decides the stop, by rule, and how the progress bar names it.
RULE_FIELDS = {"gap": ("rms_gap", "RMS gap"), "paper": ("grad_norm", "|g|/|X|")}


class _Progress:
    """A rich progress bar of the deciding value ``v``: ``log(v0/v) / log(v0/tol)``.

    One line that fits 80 columns (a pipe's width to rich): ``CVT, RMS gap < 1e-07``, the
    bar, then the value, the largest gap, mean G and the diagrams so far.
    """

    def __init__(self, rule: str, tol: float) -> None:
        from rich.progress import BarColumn, Progress, TextColumn

        self._field, label = RULE_FIELDS[rule]
        self._tol = max(tol, 1e-300)
        self._start: float | None = None
        self._progress = Progress(
            TextColumn(f"CVT, {label} < {tol:.0e}"),
            BarColumn(bar_width=10),
            TextColumn("{task.fields[status]}"),
            transient=False,
        )
        self._task = self._progress.add_task("cvt", total=1.0, status="")
        self._progress.start()

    def update(self, info: dict[str, Any]) -> None:
        value = max(float(info[self._field]), 1e-300)
        if self._start is None:
            self._start = value
        span = math.log(self._start / self._tol) if self._start > self._tol else 1.0
        done = min(max(math.log(self._start / value) / span, 0.0), 1.0) if span > 0 else 1.0
        status = (
            f"{value:.2e} max {info['max_gap']:.1e} G {info['mean_G']:.6f} "
            f"{info['evaluations']} diagrams"
        )
        self._progress.update(self._task, completed=done, status=status)

    def close(self) -> None:
        self._progress.stop()


__all__ = ["CVTResult", "GAP_TOL", "PAPER_TOL", "RULES", "cvt", "default_tol"]
