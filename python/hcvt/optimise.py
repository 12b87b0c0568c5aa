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

import hcvt._core as _core
from hcvt.core_results import RestrictedDelaunayArrays
from hcvt.density import DEFAULT_QUADRATURE_DEGREE, DensityLike, Polynomial, core_arguments
from hcvt.diagram import Diagram, as_sites, as_weights
from hcvt.draw import Shows
from hcvt.geometry.domain import Domain
from hcvt.lazy import load

RULES = ("gap", "paper")
#: Default tolerance of ``rule="gap"`` on the RMS of ``|x_i - c_i| / V_i^(1/d)``.
GAP_TOL = 1e-7
#: Default tolerance of ``rule="paper"`` on ``‖g‖/‖X‖`` in input coordinates (the paper's).
PAPER_TOL = 1e-10
#: Default tolerance of ``volumes=`` on every cell's ``|V_i - v_i| / v_i``.
VOLUME_TOL = 1e-8
#: The method of ``volumes=`` when none is given.
CAPACITY_METHOD = "lbfgs"


def default_tol(rule: str) -> float:
    """The tolerance used for ``rule`` when none is given: 1e-7 (gap) or 1e-10 (paper)."""
    return float(_core.check_settings("lbfgs", rule, None, 0, 1))


def fastest_method(
    domain: Domain, density: DensityLike = None, *, partitioned: bool = False
) -> str:
    """The optimiser :func:`hcvt.cvt` runs when given none: the fastest the core has here.

    Newton (the exact Hessian, truncated CG in a trust region) wherever the core sums its
    Hessian: polygons, solids, plain boxes, the sphere (its Riemannian Hessian) and
    triangle surfaces (its arcs weighted by the bisectors' slopes against the triangles),
    without a density or with a :class:`~hcvt.density.Polynomial` (on the sphere: with any
    density, its arcs weighted by ρ at Gauss–Legendre nodes; on a surface: none), in one
    process. It needs 3-5x fewer
    diagrams than L-BFGS from random sites and was 2.6-3.7x faster to the paper's rule in
    every row of ``docs/results/bench_cvt.txt`` (square 1k, 5k; star 2k, 10k; ball 1k, 5k;
    medians of 3 seeds) and 2.6-3.4x to the default rule in the four rows where L-BFGS
    reached it, and faster in all six hierarchical rows of
    ``docs/results/bench_hierarchy.txt``; on the sphere it converges the icosahedral MPAS
    sizes in 5 diagrams against L-BFGS's 33-118 (``benchmarks/sphere.py``); with the 4:1
    band density (2,584 sites, R = 6371 km, graded random start, seed 0, under load) Newton
    took 146 diagrams / 22 s to the default rule where L-BFGS had not reached it after 500 /
    49 s, and 97 / 14 s to the paper's against L-BFGS's 200-300 / 20-30 s
    (``benchmarks/sphere_density_newton.py`` runs the 3 seeds and 10,000 sites). On the
    bunny, kitten and fandisk at 2,000 and 5,000 sites (random by area, medians of 3 seeds,
    CPU seconds, one thread, under load) Newton reached the default rule in 87-147
    diagrams against L-BFGS's 310-606 (two rows stopped at 600 iterations short of it),
    2.4-4.4x faster in every row; to remesh's RMS gap 1e-2 L-BFGS was faster (11-13
    diagrams against 15-18, Newton 1.3-1.5x its seconds), so :func:`hcvt.remesh` keeps
    L-BFGS (``docs/results/surface_newton.txt``, ``benchmarks/surface_newton.py``).
    Elsewhere L-BFGS: a periodic box, a region of the sphere (no Hessian summed there
    yet), a sampled density in a flat domain (its Hessian is not exact), a partitioned run
    (``client=``: L-BFGS and Lloyd only).

    Returns
    -------
    str
        ``"newton"`` or ``"lbfgs"``.
    """
    # On the sphere every density is sampled, its arcs too, and Newton measured faster.
    # On a surface the arcs' terms are not weighted by a density (the core refuses it).
    polynomial = isinstance(density, Polynomial) and not domain.is_surface
    exact_hessian = density is None or polynomial or domain.is_sphere
    if domain.is_sphere_region:
        return "lbfgs"  # no Hessian summed on a region of the sphere yet
    summed = not any(domain.periodic)
    if not summed or not exact_hessian or partitioned:
        return "lbfgs"
    return "newton"


def check_rule(rule: str) -> None:
    """Raise ``ValueError`` unless ``rule`` is ``"gap"`` or ``"paper"`` (the core's check)."""
    default_tol(rule)


@dataclass(repr=False)
class CVTResult(Shows):
    """The outcome of :func:`cvt`.

    ``repr`` is one line (sites, how it stopped, cost, mean G); in Jupyter the final
    diagram's picture shows beside a summary (:class:`hcvt.draw.Shows`).

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
        ``"converged"``, ``"max_iter"``, ``"interrupted"`` (the callback asked) or
        ``"stalled"``: no site moved by more than round-off (1e-12 of the mean spacing)
        and the energy did not change beyond it for 3 iterations, and again for 3 after
        a restart (L-BFGS's memory forgotten: its next direction is the Lloyd step).
    iterations : int
        Steps taken.
    evaluations : int
        Diagrams computed (one per energy-and-gradient evaluation).
    seconds : float
        Wall time of the optimisation.
    weights : ndarray of float64, shape (n,), or None
        With ``volumes``: the weights of the final power diagram, L² (``diagram`` is that
        power diagram); else None. The history then also has ``max_volume_error``
        (``max_i |V_i - v_i| / v_i`` of each outer iteration's diagram) and
        ``newton_steps`` (its transport's Newton steps); one record per outer iteration.
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
    weights: NDArray[np.float64] | None = field(default=None, repr=False)
    #: On a surface: the restricted Delaunay triangulation of ``sites`` (core's frame),
    #: computed with ``diagram``; :func:`hcvt.remesh` reads it instead of recomputing. An
    #: ``__init__`` field, so that ``dataclasses.replace`` carries it along.
    _triangulation: RestrictedDelaunayArrays | None = field(default=None, repr=False, compare=False)

    @property
    def mean_G(self) -> float:  # noqa: N802 (the paper's G)
        """Mean G of the final diagram (paper eq. 3)."""
        return self.diagram.mean_G

    @property
    def energy(self) -> float:
        """CVT energy of the final sites, L^(d+2)."""
        return self.diagram.energy

    def __repr__(self) -> str:
        return (
            f"<hcvt.CVTResult n={len(self.sites)} d={self.sites.shape[1]} {self.stop_reason} "
            f"({self.rule} rule, tol {self.tol:.3g}) after {self.iterations} iterations, "
            f"{self.evaluations} diagrams, {self.seconds:.3g} s; mean G={self.mean_G:.6f}>"
        )

    def _summary_rows(self) -> dict[str, str]:
        gap = self.history.get("rms_gap")
        rows = {
            "stopped": f"{self.stop_reason} ({self.rule} rule, tol {self.tol:.3g})",
            "iterations": f"{self.iterations} ({self.evaluations} diagrams, {self.seconds:.3g} s)",
        }
        if gap is not None and len(gap):
            rows["RMS gap"] = f"{float(gap[0]):.3g} -> {float(gap[-1]):.3g}"
        return rows | super()._summary_rows()


def check_fixed(fixed: ArrayLike, n: int) -> NDArray[np.bool_]:
    """``fixed`` as a contiguous bool array of shape (n,), one flag per site.

    Raises ValueError naming the problem: not of dtype bool (0/1 integers are refused, so
    that a list of indices is not taken for flags), or not of shape (n,).
    """
    mask = np.asarray(fixed)
    if mask.dtype != np.bool_:
        raise ValueError(f"fixed must be an array of bool, one per site, got dtype {mask.dtype}")
    if mask.shape != (n,):
        raise ValueError(f"fixed must have shape ({n},), one flag per site, got {mask.shape}")
    return np.ascontiguousarray(mask)


def cvt(
    domain: Domain,
    sites: ArrayLike,
    method: str | None = None,
    *,
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 10_000,
    memory: int = 7,
    callback: Callable[[dict[str, Any]], Any] | None = None,
    progress: bool = False,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
    volumes: ArrayLike | None = None,
    normalise: bool = False,
    volume_tol: float = VOLUME_TOL,
    fixed: ArrayLike | None = None,
) -> CVTResult:
    """Move ``sites`` to a centroidal Voronoi tessellation of ``domain``, in this process.

    :func:`hcvt.cvt` without ``client``, which documents the parameters; ``method=None``
    is :func:`fastest_method`, or with ``volumes`` Bourne et al.'s alternation (``"lloyd"``),
    or with ``fixed`` L-BFGS (Newton does not hold sites).
    """
    if volumes is not None:
        method = capacity_method(method)
    points = as_sites(sites, domain.dim)
    held = None if fixed is None else check_fixed(fixed, len(points))
    if held is not None and held.any():
        method = method or "lbfgs"
    method = method or fastest_method(domain, density)
    # The core checks the settings for both drivers (and tells the rule's default tol).
    tol = _core.check_settings(method, rule, tol, max_iter, memory)
    frame = domain.frame  # the core works in it; sites, energy and history map back
    weighted = core_arguments(frame.density_to_core(density), domain.dim, quadrature_degree)
    if volumes is not None:
        if domain.is_sphere or domain.is_surface:
            raise ValueError("volumes= needs power diagrams: not on the sphere or a surface")
        weighted |= {
            "volumes": frame.quantity_to_core("masses", check_volumes(volumes, len(points))),
            "normalise": bool(normalise),
            "volume_tol": float(volume_tol),
        }
    if held is not None:
        weighted["fixed"] = held
    bar = ProgressBar(rule, tol) if progress else None
    observe = frame.observer(chain_observers(callback, bar))
    try:
        with frame.input_errors():
            out = _core.cvt(
                domain._core,
                frame.to_core(points),
                method=method,
                rule=rule,
                tol=float(tol),
                max_iter=int(max_iter),
                memory=int(memory),
                callback=observe,
                **weighted,
                **frame.core_arguments(),
            )
    finally:
        if bar is not None:
            bar.close()
    history = frame.history({key: np.asarray(value) for key, value in out["history"].items()})
    sites_out = frame.to_input("sites", out["sites"])
    triangulation = None
    if domain.is_surface:
        # Free in space while minimising (Yan et al. 2009); onto the surface at the end
        # (through the surface's own BVH), where the diagram is then taken, with the
        # restricted Delaunay triangulation it gives on the way (remesh reads it).
        core_sites, _ = domain._core.closest(out["sites"])
        if held is not None:
            core_sites[held] = out["sites"][held]  # on the surface already: not projected
        # Sites may project to one point (beyond a convex corner held by a site, or over
        # a flat face, one of them there already: fandisk, n = 20,000, features 30°):
        # those not held stay where the optimiser left them (distinct points there).
        order = np.lexsort(core_sites.T[::-1])
        same = (core_sites[order[1:]] == core_sites[order[:-1]]).all(axis=1)
        clash = np.zeros(len(core_sites), dtype=bool)
        clash[order[1:][same]] = clash[order[:-1][same]] = True
        if held is not None:
            clash &= ~held
        core_sites[clash] = out["sites"][clash]
        sites_out = frame.to_input("sites", core_sites)
        with frame.input_errors():
            triangulation = _core.restricted_delaunay(domain._core, core_sites, with_diagram=True)
        out["sites"], out["diagram"] = core_sites, triangulation.pop("diagram")
    if any(domain.periodic):
        # Wrapped by the core in its frame; again here, where rounding may touch `hi`.
        sites_out = domain.wrap(sites_out)
    if held is not None:
        # Never moved: the input's bits, not their round trip through the frame.
        sites_out[held] = points[held]
    weights = frame.to_input("weights", out["weights"]) if "weights" in out else None
    return CVTResult(
        sites=sites_out,
        diagram=Diagram(
            domain, sites_out, out["diagram"], density, core_sites=out["sites"], weights=weights
        ),
        history=history,
        rule=rule,
        tol=float(tol),
        converged=out["stop_reason"] == "converged",
        stop_reason=out["stop_reason"],
        iterations=int(out["iterations"]),
        evaluations=int(out["evaluations"]),
        seconds=float(history["seconds"][-1]),
        weights=weights,
        _triangulation=triangulation,
    )


def capacity_method(method: str | None) -> str:
    """The method of a CVT with prescribed volumes (``method=None``: ``"lbfgs"``).

    ``"lloyd"`` is Bourne et al.'s alternation (transport, then sites to centroids);
    ``"lbfgs"`` is L-BFGS on the transport cost, each trial a warm-started transport;
    ``"newton"`` is Newton in a trust region on the transport cost with its exact
    Hessian in the sites, the weights eliminated (no density).
    :func:`fastest_method` does not apply.
    """
    if method not in (None, "lloyd", "lbfgs", "newton"):
        raise ValueError(
            "volumes= takes method None, 'lloyd' (Bourne et al.'s alternation: optimal "
            "transport, then sites to centroids), 'lbfgs' (on the transport cost) or "
            f"'newton' (the weights eliminated), got {method!r}"
        )
    return method or CAPACITY_METHOD


def check_volumes(volumes: ArrayLike, n: int) -> NDArray[np.float64]:
    """``volumes`` as float64 (n,), each finite and positive; else ValueError naming the row."""
    values = as_weights(volumes, n, "volumes")
    if np.any(values <= 0):
        bad = int(np.flatnonzero(values <= 0)[0])
        raise ValueError(f"volume {bad} must be positive, got {values[bad]}")
    return values


def chain_observers(
    callback: Callable[[dict[str, Any]], Any] | None, bar: ProgressBar | None
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


class ProgressBar:
    """A rich progress bar of the deciding value ``v``: ``log(v0/v) / log(v0/tol)``.

    One line that fits 80 columns (a pipe's width to rich): ``CVT, RMS gap < 1e-07``, the
    bar, then the value, the largest gap, mean G and the diagrams so far.
    """

    def __init__(self, rule: str, tol: float) -> None:
        progress = load("rich.progress")
        BarColumn, Progress, TextColumn = (  # noqa: N806 (rich's class names)
            progress.BarColumn,
            progress.Progress,
            progress.TextColumn,
        )
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


__all__ = [
    "CVTResult",
    "GAP_TOL",
    "PAPER_TOL",
    "RULES",
    "VOLUME_TOL",
    "cvt",
    "default_tol",
    "fastest_method",
]
