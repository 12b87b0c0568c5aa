"""Prescribed cell masses: semi-discrete optimal transport by power diagrams (DESIGN §14).

:func:`optimal_transport` finds the weights ``w`` whose power diagram (cell ``i`` the points
where ``|x - z_i|² - w_i`` is least) gives each cell the mass asked for. The iteration runs
in the Rust core (``hcvt-core/src/optimise/transport/``): damped Newton on the weights
(Kitagawa, Mérigot and Thibert 2019) with the exact Hessian, the graph Laplacian of the
power diagram with edge weights ``∫_F ρ / (2|z_i - z_j|)``, solved in 2D by a sparse
Cholesky factorisation on the first step and by conjugate gradients preconditioned by that
factor on the later ones (factorised afresh only if 30 iterations miss the step's goal);
in 3D, or when the face graph is not connected, by conjugate gradients preconditioned by
the diagonal. Each step is halved until no cell holds less than half of
``min(initial mass, target)`` and the mass error has dropped; a trial diagram stops at the
first cell below that floor (the trial is rejected either way). The first step from zero
weights tries half a step first, the others a full one: every trial costs a power diagram.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import hcvt._core as _core
from hcvt.density import DEFAULT_QUADRATURE_DEGREE, DensityLike, core_arguments
from hcvt.diagram import Diagram, as_sites, as_weights
from hcvt.geometry.domain import Domain


@dataclass
class TransportResult:
    """What :func:`optimal_transport` found.

    Attributes
    ----------
    weights : ndarray of float64, shape (n,)
        The power diagram's weights, L² (defined up to a common constant).
    diagram : Diagram
        The power diagram of ``weights``: ``diagram.mass`` are the cells' masses.
    targets : ndarray of float64, shape (n,)
        The masses aimed at, ρ·L^d (``masses``, scaled to the domain's mass when
        normalised).
    max_error : float
        ``max_i |m_i - ν_i| / ν_i`` of ``diagram``.
    converged : bool
        ``max_error <= tol``.
    history : dict of ndarray
        Per Newton step: ``max_error`` before it, ``step`` (the length taken, 1 for a full
        step), ``cg_iterations``, ``diagrams`` (computed for the step) and ``min_mass``
        (the smallest cell after it, ρ·L^d).
    """

    weights: NDArray[np.float64]
    diagram: Diagram
    targets: NDArray[np.float64]
    max_error: float
    converged: bool
    history: dict[str, NDArray[Any]]

    @property
    def iterations(self) -> int:
        """Newton steps taken."""
        return len(self.history["step"])


def optimal_transport(
    domain: Domain,
    sites: ArrayLike,
    masses: ArrayLike,
    *,
    density: DensityLike = None,
    tol: float = 1e-10,
    max_iter: int = 100,
    normalise: bool = False,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
) -> TransportResult:
    """The power diagram of ``sites`` in ``domain`` whose cell ``i`` has mass ``masses[i]``.

    Parameters
    ----------
    domain : Domain
        A polygon, solid or box (periodic or not); not the sphere. Length unit L.
    sites : array_like of float, shape (n, d)
        Distinct points inside the domain, L.
    masses : array_like of float, shape (n,)
        Positive target masses, ρ·L^d (areas or volumes without a density). They must
        sum to the domain's mass ``∫_Ω ρ`` (to 1e-9 relative), unless ``normalise``.
    density : Polynomial, SizingField or callable, optional
        A density ρ > 0 (:mod:`hcvt.density`) the masses are measured with. With a
        polynomial the Hessian's face terms are exact; with a sampled one they are the
        geometric face measures (an approximate Hessian: more Newton steps).
    tol : float, default 1e-10
        Stop when every cell's mass is within ``tol`` of its target, relatively.
    max_iter : int, default 100
        Most Newton steps; ``converged`` is False if they run out.
    normalise : bool, default False
        Treat ``masses`` as relative: scale them to sum to the domain's mass.
    quadrature_degree : int, default 4
        Degree (1 to 5) of the simplex rule that samples a callable density.

    Returns
    -------
    TransportResult
        ``weights`` (n,), ``diagram`` (the power diagram), ``history``.

    Raises
    ------
    ValueError
        Masses of the wrong shape, not finite and positive, or not summing to the domain's
        mass; the sphere; a step that cannot keep every cell from emptying.
    InvalidSitesError
        As :func:`hcvt.voronoi`.

    Examples
    --------
    Two sites in the unit square, one cell three times the other:

    >>> import hcvt
    >>> square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    >>> out = hcvt.optimal_transport(square, [[0.25, 0.5], [0.75, 0.5]], [0.75, 0.25])
    >>> out.diagram.volume.round(12)
    array([0.75, 0.25])
    """
    points = as_sites(sites, domain.dim)
    targets = as_weights(masses, len(points), "masses")
    frame = domain.frame
    weighted = core_arguments(frame.density_to_core(density), domain.dim, quadrature_degree)
    core_sites = frame.to_core(points)
    with frame.input_errors():
        arrays = _core.optimal_transport(
            domain._core,
            core_sites,
            frame.quantity_to_core("masses", targets),
            tol=tol,
            max_iter=max_iter,
            normalise=normalise,
            **weighted,
        )
    weights = frame.to_input("weights", arrays["weights"])
    steps = arrays["history"]
    history: dict[str, NDArray[Any]] = {
        "max_error": steps["max_error"],
        "step": steps["step"],
        "cg_iterations": steps["cg_iterations"],
        "diagrams": steps["diagrams"],
        "min_mass": frame.to_input("masses", steps["min_mass"]),
    }
    return TransportResult(
        weights=weights,
        diagram=Diagram(
            domain, points, arrays["diagram"], density, core_sites=core_sites, weights=weights
        ),
        targets=frame.to_input("masses", arrays["targets"]),
        max_error=arrays["max_error"],
        converged=arrays["converged"],
        history=history,
    )
