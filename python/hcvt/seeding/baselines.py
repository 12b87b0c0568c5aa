"""Baselines the paper compares against: the global Monte-Carlo CVT of Lu et al. (2012).

Lin Lu, Feng Sun, Hao Pan, Wenping Wang, "Global optimization of centroidal Voronoi
tessellation with Monte Carlo approach", IEEE TVCG 18(11), 2012. The hierarchical paper
ran it with "the parameter values advised" there and 200 updates. That paper's exact
perturbation radius and acceptance rule could not be checked (ALGORITHMS.md §4); what is
implemented is the Monte-Carlo-with-minimisation (basin hopping) scheme it describes,
with **reconstructed** parameters ``radius`` (alpha) and ``step`` (beta):

    X <- L-BFGS(X0)
    repeat `updates` times:
        pick a random site c
        move every site within alpha*h of c by a uniform displacement of at most beta*h
        X' <- L-BFGS(perturbed X)
        if E(X') < E(X): X <- X'        (greedy acceptance, zero temperature)

with ``h = (V / n)^(1/d)`` the mean cell size.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt.density import DEFAULT_QUADRATURE_DEGREE, DensityLike
from hcvt.diagram import Diagram
from hcvt.draw import Shows
from hcvt.geometry.domain import Domain
from hcvt.lazy import load
from hcvt.optimise import cvt
from hcvt.seeding.initialisation import RandomState, random_state


@dataclass(repr=False)
class MonteCarloResult(Shows):
    """Outcome of :func:`global_monte_carlo`; shows its diagram in Jupyter."""

    sites: NDArray[np.float64]  # (n, d) the best sites found
    diagram: Diagram  # their diagram
    # Arrays per field, as CVTResult.history, one entry per update (index 0: the first local
    # minimisation): energy (of the minimum the update reached), best_energy (kept after it,
    # non-increasing), mean_G (kept), accepted (bool; index 0 True), seconds (since start).
    history: dict[str, NDArray[Any]]
    iterations: int  # L-BFGS iterations over every local minimisation
    evaluations: int  # diagrams computed
    seconds: float

    @property
    def accepted(self) -> int:
        """Number of accepted perturbations (the first minimisation not counted)."""
        return int(self.history["accepted"][1:].sum())

    def __repr__(self) -> str:
        updates = len(self.history["accepted"]) - 1
        return (
            f"<hcvt.MonteCarloResult n={len(self.sites)} d={self.sites.shape[1]} "
            f"{updates} updates, {self.accepted} accepted, {self.iterations} iterations, "
            f"{self.seconds:.3g} s; mean G={self.diagram.mean_G:.6f}>"
        )


def global_monte_carlo(
    domain: Domain,
    sites: ArrayLike,
    *,
    updates: int = 200,
    radius: float = 2.0,
    step: float = 0.5,
    seed: int = 0,
    rng: RandomState = None,
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 2000,
    progress: bool = False,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
) -> MonteCarloResult:
    """Global Monte-Carlo CVT (Lu et al. 2012, reconstructed; see the module doc).

    Parameters
    ----------
    domain : Domain
    sites : array_like, shape (n, d)
        Start; every site inside the domain.
    updates : int, default 200
        Perturbations tried (the paper's K).
    radius, step : float
        Reconstructed parameters alpha and beta, in units of the mean cell size h: sites
        within ``radius * h`` of the chosen site move by up to ``step * h`` per axis.
        A move that would leave the domain is not made (the site stays).
    seed : int
        Seeds the choice of sites and displacements.
    rng : int, numpy.random.Generator or None, optional
        Random state as numpy takes it (SPEC 7); overrides ``seed``.
    rule, tol, max_iter
        Stopping rule, its tolerance and the iteration cap of each L-BFGS minimisation
        (see :func:`hcvt.cvt`).
    progress : bool
        Show a rich progress bar over the updates.
    density : Polynomial, SizingField or callable, optional
        A density ρ (:mod:`hcvt.density`): every minimisation and energy comparison is
        ρ-weighted. The perturbation radius stays in units of the mean spacing.
    quadrature_degree : int, default 4
        Degree of the simplex rule that samples a callable density.

    Returns
    -------
    MonteCarloResult
        The lowest-energy CVT found and the history of every update.
    """
    if int(updates) != updates or updates < 0:
        raise ValueError(f"updates must be a non-negative integer, got {updates!r}")
    generator = np.random.default_rng(random_state(seed, rng))
    start = time.perf_counter()
    minimise = partial(
        cvt,
        method="lbfgs",
        rule=rule,
        tol=tol,
        max_iter=max_iter,
        density=density,
        quadrature_degree=quadrature_degree,
    )
    best = minimise(domain, sites)
    n, dim = best.sites.shape
    h = (domain.volume / n) ** (1.0 / dim)
    iterations, evaluations = best.iterations, best.evaluations
    records = [(best.diagram.energy, best.diagram.energy, best.diagram.mean_G, True)]
    times = [time.perf_counter() - start]
    for _ in _progress(range(int(updates)), progress):
        trial_sites = perturb(domain, best.sites, generator, radius * h, step * h)
        trial = minimise(domain, trial_sites)
        iterations += trial.iterations
        evaluations += trial.evaluations
        accepted = trial.diagram.energy < best.diagram.energy
        if accepted:
            best = trial
        records.append((trial.diagram.energy, best.diagram.energy, best.diagram.mean_G, accepted))
        times.append(time.perf_counter() - start)
    energy, best_energy, mean_g, accepted_flags = map(np.asarray, zip(*records, strict=True))
    history = {
        "energy": energy.astype(np.float64),
        "best_energy": best_energy.astype(np.float64),
        "mean_G": mean_g.astype(np.float64),
        "accepted": accepted_flags.astype(bool),
        "seconds": np.asarray(times),
    }
    return MonteCarloResult(
        sites=best.sites,
        diagram=best.diagram,
        history=history,
        iterations=int(iterations),
        evaluations=int(evaluations),
        seconds=time.perf_counter() - start,
    )


def perturb(
    domain: Domain,
    sites: NDArray[np.float64],
    rng: np.random.Generator,
    radius: float,
    step: float,
) -> NDArray[np.float64]:
    """Sites within ``radius`` of a random site moved by up to ``step`` per axis.

    Moves that would leave the domain are dropped, so the result is inside it.
    """
    centre = sites[rng.integers(len(sites))]
    near = np.flatnonzero(np.sum((sites - centre) ** 2, axis=1) <= radius**2)
    moved = sites[near] + rng.uniform(-step, step, size=(len(near), sites.shape[1]))
    inside = domain.contains(moved)
    out = sites.copy()
    out[near[inside]] = moved[inside]
    return out


def _progress(items: range, show: bool):
    if not show:
        return items
    return load("rich.progress").track(items, description="Monte-Carlo updates", transient=True)
