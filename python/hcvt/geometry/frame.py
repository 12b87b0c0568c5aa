"""One frame for the work: each domain moved to its own centre and scaled to unit size, once.

The core computes in coordinates ``x' = (x - c) / s``, where ``x`` is the input's (length
unit L) and the :class:`Frame` holds ``c`` (d,) and ``s > 0``. Far from the origin, bisector
planes built from absolute coordinates lose digits (a unit cube at 1e6: mesh volumes off by
2.2e-3 relative, at 1e8 by a factor of 14); at extreme sizes second moments under- or
overflow (a cube of side 1e-90: G = NaN; of side 1e70: G = 0). In the frame every domain
is near the origin with a size near 1.

Exact where it can be:

- ``s`` is a power of two, so dividing and multiplying by it is exact (no subnormals: a
  difference below 2^-1022 · s is beyond any input);
- ``c`` is chosen per axis: 0 unless the domain's centre is more than
  :data:`TRANSLATE_FACTOR` sizes from the origin, else the centre rounded to a multiple of
  ``g``, the power of two at or above the size. Then ``x - c`` is exact for every ``x``
  within the domain's box (both are multiples of ``ulp(x) <= g`` and ``|x - c| < 2^53
  ulp(x)``), so boundary vertices and sites inside map to the frame and back bit for bit;
- a domain of size in ``[2^-IDENTITY_OCTAVES, 2^IDENTITY_OCTAVES]`` centred within
  :data:`TRANSLATE_FACTOR` sizes of the origin gets the identity frame: its results are
  bitwise those of the core on the input itself.

Results come back through one table, :data:`UNITS`: a quantity of unit ``L^p`` is
multiplied by ``s^p``, a position also shifted by ``c``; G and the neighbour indices are
unchanged. A result whose value in L is outside float64 (a volume of 1e-150³, a second
moment of 1e100^5) raises :class:`hcvt.errors.UnrepresentableError` when it is asked for;
the others stay available. A position comes back rounded once (``s · x' + c``): the
round-off of the input's own representation.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt.density import Polynomial, SizingField
from hcvt.errors import InvalidSitesError, UnrepresentableError

#: Translate an axis when the domain's centre on it is farther than this many sizes from 0.
TRANSLATE_FACTOR = 4.0
#: Leave the scale at 1 for sizes within 2^-k .. 2^k.
IDENTITY_OCTAVES = 16


@dataclass(frozen=True)
class Unit:
    """``L^(a·d + b)``, and whether the quantity is a position (shifted by ``c``)."""

    per_dim: int
    extra: int
    position: bool = False

    def power(self, dim: int) -> int:
        """The exponent of L in ``dim`` dimensions."""
        return self.per_dim * dim + self.extra


#: The unit of every result the core returns, by name: the one place where results map back.
UNITS: dict[str, Unit | None] = {
    # diagrams (hcvt.diagram, hcvt.distributed)
    "volume": Unit(1, 0),
    "mass": Unit(1, 0),  # ∫ρ dx with ρ evaluated in input coordinates
    "centroid": Unit(0, 1, position=True),
    "second_moment": Unit(1, 2),
    "G": Unit(0, 0),
    "energy_terms": Unit(1, 2),
    "energy": Unit(1, 2),
    "gradient": Unit(1, 1),
    "first": Unit(1, 1),  # moments about the sites (partitions)
    "boundary_measure": Unit(1, -1),
    "neighbor_measures": Unit(1, -1),
    "reach2": Unit(0, 2),
    # power diagrams and optimal transport (hcvt.transport)
    "weights": Unit(0, 2),
    "masses": Unit(1, 0),
    # a partitioned CVT's per-part step (distributed/partition.py)
    "shift": Unit(0, 1),  # a displacement: L, no centre
    "direction": Unit(0, 1),
    "pair_s": Unit(0, 1),  # L-BFGS pairs: site steps ...
    "pair_y": Unit(1, 1),  # ... and gradient changes
    "precond": Unit(-1, 0),  # 1 / (2 m_i)
    # conforming meshes and sites
    "points": Unit(0, 1, position=True),
    "sites": Unit(0, 1, position=True),
    # domains
    "first_moment": Unit(1, 1),  # about the frame's centre; see Frame.first_moment
    # not quantities: indices and counts
    "neighbor_offsets": None,
    "neighbor_sites": None,
    "neighbor_images": None,  # image shifts k, integers
    "face_offsets": None,
    "face_vertices": None,
    "owner": None,
    "neighbour": None,
    "boundary_element": None,
    "open_chains": None,
    "computed": None,
    # CVT history columns (hcvt.optimise): grad_norm comes from the core in L^d already
    "mean_G": Unit(0, 0),
    "rms_gap": Unit(0, 0),
    "max_gap": Unit(0, 0),
    "grad_norm": None,
    "pinned": None,
    "seconds": None,
    "evaluations": None,
    "step": None,
    # a capacity-constrained CVT's (hcvt.cvt with volumes): relative error, counts
    "max_volume_error": Unit(0, 0),
    "newton_steps": None,
}


@dataclass(frozen=True, eq=False)
class Frame:
    """``x = scale · x' + centre``: where the core's coordinates sit in the input's.

    Attributes
    ----------
    centre : ndarray, shape (d,)
        ``c``, in L; zeros on the axes that are not moved.
    scale : float
        ``s``, a power of two, in L.
    """

    centre: NDArray[np.float64]
    scale: float

    @classmethod
    def fit(cls, vertices: ArrayLike) -> Frame:
        """The frame of a domain whose boundary vertices are ``vertices`` (V, d), finite.

        Examples
        --------
        >>> Frame.fit([[0.0, 0.0], [1.0, 1.0]]).is_identity
        True
        >>> f = Frame.fit([[1e6, 1e6], [1e6 + 1, 1e6 + 1]])
        >>> f.centre.tolist(), f.scale
        ([1000000.0, 1000000.0], 1.0)
        >>> Frame.fit([[0.0, 0.0], [3e-90, 3e-90]]).scale == 2.0**-298
        True
        """
        v = np.asarray(vertices, dtype=np.float64)
        lo, hi = v.min(axis=0), v.max(axis=0)
        size = float(np.max(hi - lo))
        if not (size > 0 and math.isfinite(size)):
            # Validation of the domain reports it; the identity keeps the input as given.
            return cls(np.zeros(v.shape[1]), 1.0)
        octave = math.frexp(size)[1]  # size < 2^octave <= 2 size
        grain = 2.0**octave
        scale = 1.0 if abs(octave) <= IDENTITY_OCTAVES else math.ldexp(1.0, octave - 1)
        middle = 0.5 * lo + 0.5 * hi  # no overflow near the largest floats
        far = np.abs(middle) > TRANSLATE_FACTOR * size
        with np.errstate(over="ignore", invalid="ignore"):
            rounded = np.round(middle / grain) * grain
        centre = np.where(far, np.where(np.isfinite(rounded), rounded, middle), 0.0)
        return cls(centre, scale)

    @classmethod
    def identity(cls, dim: int) -> Frame:
        """The frame of the input itself."""
        return cls(np.zeros(dim), 1.0)

    @property
    def dim(self) -> int:
        """2 or 3."""
        return len(self.centre)

    @property
    def is_identity(self) -> bool:
        """Whether the core works on the input coordinates themselves (bit for bit)."""
        return self.scale == 1.0 and not np.any(self.centre)

    # ------------------------------------------------------------------ into the frame
    def to_core(self, points: NDArray[np.float64], name: str = "sites") -> NDArray[np.float64]:
        """``(x - c) / s`` of ``points`` (m, d), C-contiguous; exact inside the domain's box.

        Raises
        ------
        InvalidSitesError
            A finite row whose frame coordinates are not (it lies so far from the domain,
            against the domain's size, that float64 cannot hold where it is), by row.
        """
        if self.is_identity:
            return points
        with np.errstate(over="ignore", invalid="ignore"):
            out = np.ascontiguousarray((points - self.centre) / self.scale)
        lost = np.isfinite(points).all(axis=1) & ~np.isfinite(out).all(axis=1)
        if lost.any():
            k = int(np.flatnonzero(lost)[0])
            raise InvalidSitesError(
                f"{name[:-1] if name.endswith('s') else name} {k} at {points[k].tolist()} is "
                f"too far from the domain (size about {self.scale:.3g}) to be represented in "
                f"its frame: {int(lost.sum())} such row(s)"
            )
        return out

    def steps_to_core(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Sites (m, d) a run's own steps left in the domain, as :meth:`to_core` maps them.

        A partitioned run's parts hold sites that came out of the core's steps: they go
        back as positions (on the sphere without being pushed onto it again, since a second
        normalisation would move them off the single process's iterates by round-off).
        """
        return self.to_core(points)

    def onto_domain(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """``points`` (m, d) as the core takes them, in L again: unchanged here.

        On the sphere they are pushed onto it, once, as :meth:`to_core` does for one
        process (:meth:`steps_to_core` then leaves them there).
        """
        return points

    def quantity_to_core(self, name: str, value: NDArray[np.float64]) -> NDArray[np.float64]:
        """A quantity ``name`` (:data:`UNITS`) in L as the core takes it.

        The inverse of :meth:`to_input`: positions by :meth:`to_core`, the rest divided by
        ``s^p`` (exact for a power-of-two ``s``).
        """
        unit = UNITS[name]
        if unit is None or self.is_identity:
            return value
        if unit.position:
            return self.to_core(value, name)
        power = unit.power(self.dim)
        return np.ascontiguousarray(_times_scale_power(np.asarray(value), -power, self.scale))

    def density_to_core(self, density: Any) -> Any:
        """A density in input coordinates as one in the frame: ``ρ'(x') = ρ(s x' + c)``.

        A :class:`hcvt.density.Polynomial` is expanded about ``c`` (exact when ``c = 0``:
        the coefficients times powers of two), so its quadrature stays exact; a callable or
        :class:`hcvt.density.SizingField` is evaluated at the points mapped back.
        """
        if density is None or self.is_identity:
            return density
        s, c = self.scale, self.centre
        if isinstance(density, Polynomial):
            # ρ(s x' + c) = ρ(c) + s (b + 2 Q c)·x' + s² x'ᵀ Q x'
            constant, linear, quadratic = density.coefficients(density.dim or self.dim)
            b, q = np.asarray(linear), np.asarray(quadratic)
            with np.errstate(over="ignore", invalid="ignore"):
                moved = (
                    float(density(c[None, :])[0]) if np.any(c) else constant,
                    s * (b + 2.0 * (q @ c)),
                    (s * s) * q,
                )
            if not all(np.all(np.isfinite(part)) for part in moved):
                raise UnrepresentableError(
                    f"the polynomial density {density!r} cannot be written in the domain's "
                    f"frame (scale {s:.3g}): its coefficients overflow; pass it as a callable"
                )
            return Polynomial(*moved)
        rho = density.density(self.dim) if isinstance(density, SizingField) else density
        if not callable(rho):
            return density  # core_arguments names the type

        def in_input(points: NDArray[np.float64]) -> Any:
            return rho(self.points_to_input(points))

        return in_input

    # ------------------------------------------------------------------ back out
    def points_to_input(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """``s · x' + c``, rounded once."""
        if self.is_identity:
            return points
        return np.asarray(points) * self.scale + self.centre

    def to_input(self, name: str, value: Any) -> Any:
        """The core's result ``name`` in the input's unit (:data:`UNITS`).

        Raises
        ------
        UnrepresentableError
            Some entry is finite and nonzero in the frame but overflows to infinity, or
            underflows to zero or a subnormal, in L.
        """
        unit = UNITS[name]
        if unit is None or self.is_identity:
            return value
        if unit.position:
            return self.points_to_input(value)
        power = unit.power(self.dim)
        if power == 0:
            return value
        x = np.asarray(value, dtype=np.float64)
        out = _times_scale_power(x, power, self.scale)
        finite = np.isfinite(x)
        over = finite & ~np.isfinite(out)
        under = finite & (x != 0) & ~(np.abs(out) >= np.finfo(np.float64).tiny)
        if np.any(over | under):
            k = int(np.flatnonzero(np.ravel(over | under))[0])
            what = "overflows" if np.ravel(over)[k] else "underflows"
            raise UnrepresentableError(
                f"{name} is not representable in the input's unit: entry {k} is "
                f"{np.ravel(x)[k]:.6g} in the domain's frame, times scale^{power} "
                f"({self.scale:.6g}^{power}) it {what} float64"
            )
        return out if isinstance(value, np.ndarray) else float(out)

    def volume_or_nan(self, core_volume: float) -> float:
        """A volume of the frame in L^d, NaN where float64 cannot hold it (reports)."""
        try:
            return float(self.to_input("volume", float(core_volume)))
        except UnrepresentableError:
            return float("nan")

    def first_moment(self, core_first: NDArray[np.float64], core_volume: float) -> Any:
        """``∫ x dx`` in L^(d+1) from the frame's ``∫ x' dx'`` and volume."""
        if self.is_identity:
            return core_first
        moved = np.asarray(core_first) + core_volume * self.centre / self.scale
        return self.to_input("first_moment", moved)

    @contextmanager
    def input_errors(self) -> Iterator[None]:
        """Add a site's input coordinates to an error the core raised in frame coordinates."""
        try:
            yield
        except ValueError as err:
            if self.is_identity:
                raise
            text = str(err)
            match = re.search(r"\bsites? (\d+)", text)
            where = f"; site {match.group(1)} is in the domain's frame" if match else ""
            raise type(err)(
                f"{text} (coordinates in the domain's frame x' = (x - c) / s, c = "
                f"{self.centre.tolist()}, s = {self.scale:.17g}{where})"
            ) from err

    def core_arguments(self) -> dict[str, Any]:
        """``frame=`` for ``_core.cvt``: its paper rule ``‖g‖/‖X‖`` is in L (DESIGN §7)."""
        if self.is_identity:
            return {}
        return {"frame": (self.centre.tolist(), self.scale)}

    def observer(self, observe: Callable[[dict[str, Any]], bool] | None) -> Any:
        """``observe`` seeing each iterate's ``sites`` and ``energy`` in L."""
        if observe is None or self.is_identity:
            return observe

        def in_input(info: dict[str, Any]) -> bool:
            info["sites"] = self.points_to_input(info["sites"])
            try:
                info["energy"] = self.to_input("energy", info["energy"])
            except UnrepresentableError:
                info["energy"] = float("nan")  # documented in hcvt.cvt's callback
            return observe(info)

        return in_input

    def history(self, columns: dict[str, Any]) -> History:
        """A CVT's history with every column in L (:class:`History`).

        A column float64 cannot hold in L raises when read.
        """
        out = History()
        for name, value in columns.items():
            try:
                out[name] = self.to_input(name, np.asarray(value))
            except UnrepresentableError as err:
                out.unrepresentable[name] = str(err)
        return out

    def __repr__(self) -> str:
        return f"Frame(centre={self.centre.tolist()}, scale={self.scale!r})"


class History(dict[str, Any]):
    """A dict of history columns in L.

    A column that is not representable in L (the energy of a domain 1e100 wide) is absent
    and raises :class:`UnrepresentableError` when asked for.
    """

    def __init__(self) -> None:
        super().__init__()
        self.unrepresentable: dict[str, str] = {}

    def __missing__(self, key: str) -> Any:
        if key in self.unrepresentable:
            raise UnrepresentableError(self.unrepresentable[key])
        raise KeyError(key)


def _times_scale_power(x: NDArray[np.float64], power: int, scale: float) -> NDArray[np.float64]:
    """``x · scale^power``, rounded once where ``scale^power`` is a normal float64.

    Exact for a power-of-two scale (a polygon's or a solid's frame); for the sphere's
    radius one more rounding. Where ``scale^power`` alone over- or underflows, a factor at
    a time, so that entries that fit come out right and the others as inf or 0.
    """
    try:
        factor = scale**power
    except OverflowError:  # Python floats raise where numpy would give inf
        factor = math.inf
    with np.errstate(over="ignore", under="ignore"):
        if math.isfinite(factor) and factor >= np.finfo(np.float64).tiny:
            return x * factor
        return _scaled(x, power, scale)


def _scaled(x: NDArray[np.float64], power: int, scale: float) -> NDArray[np.float64]:
    """``x · scale^power`` when ``scale^power`` alone is out of range: a factor at a time."""
    out = np.array(x, dtype=np.float64)
    step = scale if power > 0 else 1.0 / scale
    for _ in range(abs(power)):
        out *= step
    return out


__all__ = ["Frame", "History", "IDENTITY_OCTAVES", "TRANSLATE_FACTOR", "UNITS", "Unit"]
