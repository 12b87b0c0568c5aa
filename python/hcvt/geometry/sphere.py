"""The sphere of radius R about the origin as the core sees it: the unit sphere.

The core computes on the unit sphere (``hcvt-core/src/diagram/sphere.rs``); a
:class:`SphereFrame` maps sites in and results out. Sites are checked to lie on the sphere
(to :data:`ON_SPHERE_RTOL` of ``R``) and pushed onto it exactly (``x / |x|``); a result of
unit ``L^p`` comes back times ``R^p``, with ``p`` counted for cells of dimension 2 (areas
``R²``, energies and second moments ``R⁴``, arc lengths ``R``), positions times ``R``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hcvt.density import Polynomial, SizingField
from hcvt.errors import InvalidDensityError, InvalidSitesError
from hcvt.geometry.frame import Frame

#: How far from the sphere a site may lie, relative to its radius: ``| |x| − R | ≤ rtol·R``.
#: Sites given as unit vectors times ``R`` are within a few ulps; a site off by more is
#: likely on another sphere, or not a site of the sphere at all.
ON_SPHERE_RTOL = 1e-9


@dataclass(frozen=True, eq=False)
class SphereFrame(Frame):
    """``x = R · x'`` with ``x'`` on the unit sphere; cells of dimension 2.

    Attributes
    ----------
    centre : ndarray, shape (3,)
        Zeros: the sphere is about the origin.
    scale : float
        The radius ``R``, in L (any positive finite number; not rounded to a power of 2,
        so results are rounded once more than in a polygon's frame).
    """

    #: The domain is a region of the sphere (``Domain.sphere(region=...)``), which takes no
    #: density yet.
    has_region: bool = False

    @classmethod
    def of_radius(cls, radius: float, has_region: bool = False) -> SphereFrame:
        """The frame of the sphere of ``radius`` (positive and finite)."""
        return cls(np.zeros(3), float(radius), has_region)

    @property
    def dim(self) -> int:
        """2: the dimension of the cells, which every unit's power counts."""
        return 2

    @property
    def is_identity(self) -> bool:
        """Never: sites are always checked and pushed onto the unit sphere."""
        return False

    def to_core(self, points: NDArray[np.float64], name: str = "sites") -> NDArray[np.float64]:
        """``x / |x|`` of ``points`` (m, 3) after checking ``| |x| − R | ≤ rtol · R``.

        Raises
        ------
        InvalidSitesError
            The first row off the sphere, with its distance from the centre.
        """
        points = np.asarray(points, dtype=np.float64)
        what = name[:-1] if name.endswith("s") else name
        finite = np.isfinite(points)
        if not finite.all():
            k, j = (int(i) for i in np.argwhere(~finite)[0])
            raise InvalidSitesError(
                f"{what} {k} has a non-finite coordinate ({points[k, j]:g})".replace("nan", "NaN")
            )
        # |x| after dividing by R: |x|² itself under- or overflows for R far from 1
        unit = points / self.scale
        r = np.linalg.norm(unit, axis=1)
        off = ~(np.abs(r - 1.0) <= ON_SPHERE_RTOL)
        if off.any():
            k = int(np.flatnonzero(off)[0])
            raise InvalidSitesError(
                f"{what} {k} at {points[k].tolist()} is {r[k] * self.scale:.17g} from the "
                f"centre, not on the sphere of radius {self.scale:.17g} (relative tolerance "
                f"{ON_SPHERE_RTOL:g}): {int(off.sum())} such row(s); project them first, "
                f"x * R / |x|"
            )
        return np.ascontiguousarray(unit / r[:, None])

    def steps_to_core(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """``x / R``, not normalised: sites from the core's own steps (already retracted).

        Exact, so bitwise the single process's iterates, for a radius that is a power of
        two (1 included); other radii round once per step.
        """
        return np.ascontiguousarray(np.asarray(points, dtype=np.float64) / self.scale)

    def onto_domain(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """``R x / |x|`` after :meth:`to_core`'s check: the sites the core takes, in L."""
        return self.points_to_input(self.to_core(points))

    def density_to_core(self, density: Any) -> Any:
        """A density on the sphere of radius R as one on the unit sphere.

        A callable of position (a :class:`hcvt.density.LonLatDensity` is one) is called at
        ``R x'``; a :class:`hcvt.density.SizingField` is ``h^-4`` (cells of dimension 2).
        A constant :class:`hcvt.density.Polynomial` goes to the core as it is (the uniform
        cells, scaled); any other polynomial is sampled as a callable (every value checked).
        """
        if density is None:
            return None
        if self.has_region:
            raise NotImplementedError(
                "a density on a region of the sphere is not implemented yet (the cells' "
                "pieces are not convex there); use the whole sphere or no density"
            )
        if isinstance(density, Polynomial):
            if density.dim not in (None, 3):
                raise InvalidDensityError(
                    f"a polynomial density on the sphere is in x, y, z; got {density!r}"
                )
            if density.linear is None and density.quadratic is None:
                return density  # a constant: the same for every radius
            density = _as_function(density)
        if not (callable(density) or isinstance(density, SizingField)):
            raise TypeError(
                "density on the sphere must be a vectorised callable rho(points (m, 3)), a "
                "hcvt.density.LonLatDensity, a SizingField or a Polynomial, got "
                f"{type(density).__name__}"
            )
        return super().density_to_core(density)

    def points_to_input(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """``R · x'``."""
        return np.asarray(points) * self.scale

    def first_moment(self, core_first: NDArray[np.float64], core_volume: float) -> Any:
        """``∫ x dA`` over the sphere: zero."""
        return np.zeros(3)

    def core_arguments(self) -> dict[str, Any]:
        """``frame=`` for ``_core.cvt``: the paper's ``‖g‖/‖X‖`` in L."""
        return {"frame": ([0.0, 0.0, 0.0], self.scale)}

    def __repr__(self) -> str:
        return f"SphereFrame(radius={self.scale!r})"


def _as_function(polynomial: Polynomial) -> Any:
    """``polynomial`` as a plain callable of points (m, 3)."""

    def rho(points: NDArray[np.float64]) -> NDArray[np.float64]:
        return polynomial(points)

    return rho


def check_radius(radius: object) -> float:
    """``radius`` as a positive finite float, or a ValueError."""
    if isinstance(radius, bool) or not isinstance(radius, (int, float, np.integer, np.floating)):
        raise ValueError(f"radius must be a number, got {type(radius).__name__}")
    r = float(radius)
    if not (r > 0 and math.isfinite(r)):
        raise ValueError(f"radius must be positive and finite, got {radius!r}")
    return r


__all__ = ["ON_SPHERE_RTOL", "SphereFrame", "check_radius"]
