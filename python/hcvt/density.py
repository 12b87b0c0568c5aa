"""Densities ρ > 0 for diagrams and CVTs (DESIGN §8).

With a density the CVT energy is ``E = Σ_i ∫_cell_i ρ |x - x_i|² dx`` and the sites are
driven to the ρ-weighted centroids; asymptotically the cell size follows ``ρ^(-1/(d+2))``
(Gersho). ``density=`` takes one of

- a :class:`Polynomial` of degree ≤ 2 in the coordinates: mass, moments and energy are
  exact to round-off (a degree-4 simplex rule, evaluated in the core, integrates
  ``ρ |x - x_i|²`` exactly);
- any vectorised callable ``rho(points)`` with ``points`` of shape (m, d) returning (m,),
  sampled by a symmetric simplex rule of degree ``quadrature_degree`` (1 to 5, default 4:
  a callable that happens to be a polynomial of degree ≤ 2 is then exact too). The core
  gathers every quadrature point of a diagram and calls it once per diagram;
- a :class:`SizingField` ``h(x)`` (target spacing), i.e. ``ρ = h^-(d+2)`` (CGAL's
  convention), so that the CVT's cell size follows ``h``.

On a triangle surface (:meth:`hcvt.Domain.from_surface`; cells of dimension 2, so
``ρ = h^-4`` and a cell's size follows ``ρ^(-1/4)``) ``density=`` is a callable of
position (sampled at the triangle rule's nodes on each flat piece of a cell), a
:class:`Polynomial` in x, y, z (exact: a degree-4 triangle rule), or a per-vertex field:
a 1-D array of one value per vertex of the surface, linear on each input triangle
(exact: interpolated at each piece's corners in the core). Newton is not offered with a
density on a surface (L-BFGS and Lloyd are). :func:`hcvt.surface.curvature_density`
builds a per-vertex field from the surface's curvature.

On :meth:`hcvt.Domain.sphere` (cells of dimension 2, so ``ρ = h^-4``) a callable is a
function of position on the sphere of radius R, or a :class:`LonLatDensity` of longitude
and latitude; it is sampled on each cell's spherical triangles by a triangle rule of
``quadrature_degree`` through the radial projection and its Jacobian (no rule is exact
there: the error falls as ``h^(degree+1)``; a constant is exact to round-off). A
:class:`Polynomial` in x, y, z is sampled the same way.

ρ must be finite and positive wherever it is evaluated, else :class:`InvalidDensityError`
names the point. A callable is evaluated at quadrature points of the clipped cells' cone
pieces; in a non-convex domain some of these pieces (whose contributions cancel) lie
outside the domain but inside its bounding box: define ρ on the whole box. A polynomial is
checked at every site and boundary vertex, and each cell's mean density must be positive.

Only the weighted quantities carry ρ: ``Diagram.mass`` (``∫ρ``), ``centroid``,
``energy_terms``, ``energy`` and ``gradient``; ``volume``, ``second_moment`` and ``G``
stay geometric (``G`` measures the shape of each cell, whatever the density).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt.errors import InvalidDensityError

#: The quadrature degree of a callable unless told: 4, so that a quadratic is exact.
DEFAULT_QUADRATURE_DEGREE = 4
#: Degrees the simplex rules reach.
QUADRATURE_DEGREES = (1, 2, 3, 4, 5)
_AXES = "xyz"
# One term of Polynomial.parse: a sign, a number, a product of x, y, z (or squares).
_TERM = re.compile(
    r"([+-]?)(\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)?\*?((?:[xyz](?:\^2)?\*?)*)"
)


class Polynomial:
    """``ρ(x) = constant + linear · x + xᵀ quadratic x``, of degree ≤ 2.

    Parameters
    ----------
    constant : float
        ρ at the origin.
    linear : array_like, shape (d,), optional
        Gradient at the origin; zeros if omitted.
    quadratic : array_like, shape (d, d), optional
        The quadratic form (symmetrised: ``(A + Aᵀ)/2`` gives the same values); zeros if
        omitted.

    A constant alone works in any dimension. Call it on points (m, d) for the values.

    Examples
    --------
    >>> from hcvt.density import Polynomial
    >>> rho = Polynomial(1.0, [0.0, 2.0], [[3.0, 0.0], [0.0, 0.0]])
    >>> rho
    Polynomial(1 + 2*y + 3*x**2)
    >>> rho([[1.0, 1.0]])
    array([6.])
    >>> Polynomial.parse("1 + 2*y + 3*x^2") == rho
    True
    """

    def __init__(
        self,
        constant: float,
        linear: ArrayLike | None = None,
        quadratic: ArrayLike | None = None,
    ) -> None:
        self.constant = float(constant)
        lin = None if linear is None else np.asarray(linear, dtype=np.float64)
        quad = None if quadratic is None else np.asarray(quadratic, dtype=np.float64)
        dim = lin.shape[0] if lin is not None else quad.shape[0] if quad is not None else None
        if lin is not None and lin.shape != (dim,):
            raise ValueError(f"linear must have shape (d,), got {lin.shape}")
        if quad is not None and quad.shape != (dim, dim):
            raise ValueError(f"quadratic must have shape ({dim}, {dim}), got {quad.shape}")
        if dim is not None and dim not in (2, 3):
            raise ValueError(f"a polynomial density is in 2 or 3 dimensions, got {dim}")
        self.dim: int | None = dim
        self.linear = lin
        self.quadratic = None if quad is None else 0.5 * (quad + quad.T)
        coefficients = [
            self.constant,
            *(lin if lin is not None else []),
            *(self.quadratic.ravel() if self.quadratic is not None else []),
        ]
        if not np.all(np.isfinite(coefficients)):
            raise InvalidDensityError(f"polynomial coefficients must be finite: {self!r}")

    @classmethod
    def parse(cls, text: str, dim: int | None = None) -> Polynomial:
        """A polynomial from terms such as ``"1 + 10*x^2 - 0.5*x*y + 3*z"``.

        A safe parser (no ``eval``): a sum of terms ``[number][*]monomial`` where a
        monomial is a product of at most two of ``x``, ``y``, ``z`` (``x^2`` or ``x**2``
        for a square). ``dim`` defaults to 3 if ``z`` appears, else 2.
        """
        if re.search(r"[\d.]\s+[\d.]", text):
            raise ValueError(f"cannot read {text!r}: numbers separated by a space")
        source = text.replace(" ", "").replace("**", "^")
        parsed: list[tuple[float, list[int]]] = []
        at = 0
        while at < len(source):
            match = _TERM.match(source, at)
            if match is None or match.end() == at or (at > 0 and not match.group(1)):
                raise ValueError(f"cannot read {text!r} at {source[at:]!r}")
            if not match.group(2) and not match.group(3):
                raise ValueError(f"empty term in {text!r} at {source[at:]!r}")
            sign = -1.0 if match.group(1) == "-" else 1.0
            value = sign * float(match.group(2) or 1.0)
            axes: list[int] = []
            for name, square in re.findall(r"([xyz])(\^2)?", match.group(3)):
                axes += [_AXES.index(name)] * (2 if square else 1)
            if len(axes) > 2:
                raise ValueError(f"{match.group(0)!r} has degree {len(axes)} > 2")
            parsed.append((value, axes))
            at = match.end()
        if not parsed:
            raise ValueError("empty polynomial")
        used = max((a for _, axes in parsed for a in axes), default=-1)
        dim = dim or (3 if used == 2 else 2)
        if used >= dim:
            raise ValueError(f"{text!r} uses {_AXES[used]} in {dim} dimensions")
        constant, linear, quadratic = 0.0, np.zeros(dim), np.zeros((dim, dim))
        for value, axes in parsed:
            if not axes:
                constant += value
            elif len(axes) == 1:
                linear[axes[0]] += value
            else:
                i, j = axes
                quadratic[i, j] += value / (1.0 if i == j else 2.0)
                if i != j:
                    quadratic[j, i] += value / 2.0
        return cls(constant, linear, quadratic)

    def coefficients(self, dim: int) -> tuple[float, list[float], list[list[float]]]:
        """``(constant, linear (dim,), quadratic (dim, dim))`` for the core."""
        if self.dim is not None and self.dim != dim:
            raise InvalidDensityError(
                f"the polynomial density is in {self.dim} dimensions, the domain in {dim}"
            )
        linear = np.zeros(dim) if self.linear is None else self.linear
        quadratic = np.zeros((dim, dim)) if self.quadratic is None else self.quadratic
        return self.constant, linear.tolist(), quadratic.tolist()

    def __call__(self, points: ArrayLike) -> NDArray[np.float64]:
        """ρ at ``points`` (m, d), shape (m,)."""
        x = np.asarray(points, dtype=np.float64)
        out = np.full(x.shape[0], self.constant)
        if self.linear is not None:
            out += x @ self.linear
        if self.quadratic is not None:
            out += np.sum((x @ self.quadratic) * x, axis=1)
        return out

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Polynomial):
            return NotImplemented
        dim = self.dim or other.dim or 2
        a, b = self.coefficients(dim), other.coefficients(dim)
        return a[0] == b[0] and np.array_equal(a[1], b[1]) and np.array_equal(a[2], b[2])

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        terms = [_number(self.constant)] if self.constant != 0 else []
        if self.linear is not None:
            terms += [_term(c, _AXES[i]) for i, c in enumerate(self.linear) if c != 0]
        if self.quadratic is not None:
            q = self.quadratic
            for i in range(len(q)):
                for j in range(i, len(q)):
                    c = q[i, j] if i == j else 2.0 * q[i, j]
                    if c != 0:
                        monomial = f"{_AXES[i]}**2" if i == j else f"{_AXES[i]}*{_AXES[j]}"
                        terms.append(_term(c, monomial))
        text = " + ".join(terms) if terms else "0"
        return f"Polynomial({text.replace('+ -', '- ')})"


def _number(c: float) -> str:
    return f"{c:.17g}" if float(f"{c:g}") != c else f"{c:g}"


def _term(c: float, monomial: str) -> str:
    return monomial if c == 1 else f"-{monomial}" if c == -1 else f"{_number(c)}*{monomial}"


class SizingField:
    """A target spacing ``h(x) > 0`` (length unit L) as the density ``ρ = h^-(d+2)``.

    CGAL's convention: a CVT's cell size is proportional to ``ρ^(-1/(d+2))`` (Gersho), so
    it follows ``h`` up to a constant factor fixed by the number of sites.

    Parameters
    ----------
    h : callable
        ``h(points (m, d)) -> (m,)``, vectorised.
    """

    def __init__(self, h: Callable[[NDArray[np.float64]], ArrayLike]) -> None:
        if not callable(h):
            raise TypeError(f"a sizing field needs a callable h(points), got {h!r}")
        self.h = h

    def density(self, dim: int) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
        """The density ``h^-(d+2)`` in ``dim`` dimensions, as a vectorised callable."""

        def rho(points: NDArray[np.float64]) -> NDArray[np.float64]:
            h = np.asarray(self.h(points), dtype=np.float64)
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(h > 0, h, np.nan) ** -(dim + 2.0)

        return rho

    def __repr__(self) -> str:
        return f"SizingField({self.h!r})"


class LonLatDensity:
    """A density on the sphere given as a function of longitude and latitude, in degrees.

    A plain callable given as ``density=`` on :meth:`hcvt.Domain.sphere` is a function of
    position, ``rho(points (m, 3)) -> (m,)`` with the points on the sphere of radius R (in
    its unit); wrap a function of ``(lon, lat)`` in this class instead. It is itself that
    function of position (so it works wherever a density is evaluated): the points'
    longitude in ``(-180, 180]`` and latitude in ``[-90, 90]``, in degrees, each (m,),
    go to ``fn``.

    Parameters
    ----------
    fn : callable
        ``fn(lon (m,), lat (m,)) -> (m,)``, vectorised, degrees.

    Examples
    --------
    >>> import numpy as np
    >>> from hcvt.density import LonLatDensity
    >>> rho = LonLatDensity(lambda lon, lat: 1.0 + np.cos(np.radians(lat)))
    >>> rho(np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 2.0]])).round(12).tolist()
    [2.0, 1.0]
    """

    def __init__(self, fn: Callable[[NDArray[np.float64], NDArray[np.float64]], ArrayLike]) -> None:
        if not callable(fn):
            raise TypeError(f"LonLatDensity needs a callable fn(lon, lat), got {fn!r}")
        self.fn = fn

    def __call__(self, points: ArrayLike) -> NDArray[np.float64]:
        """ρ at ``points`` (m, 3) on a sphere about the origin, shape (m,)."""
        x = np.asarray(points, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3:
            raise InvalidDensityError(
                f"a LonLatDensity is evaluated at points (m, 3) on the sphere, got {x.shape}"
            )
        lon = np.degrees(np.arctan2(x[:, 1], x[:, 0]))
        lat = np.degrees(np.arctan2(x[:, 2], np.hypot(x[:, 0], x[:, 1])))
        return np.asarray(self.fn(lon, lat), dtype=np.float64)

    def __repr__(self) -> str:
        return f"LonLatDensity({self.fn!r})"


#: What ``density=`` accepts (an array: a surface's per-vertex field).
DensityLike = (
    Polynomial | SizingField | Callable[[NDArray[np.float64]], ArrayLike] | NDArray[Any] | None
)


def per_vertex(values: Any) -> NDArray[np.float64]:
    """A surface's per-vertex density as float64 (V,), checked finite and positive.

    Raises InvalidDensityError naming the first bad vertex (the count against the
    surface's vertices is the core's check).
    """
    array = np.ascontiguousarray(values, dtype=np.float64)
    if array.ndim != 1:
        raise InvalidDensityError(
            f"a per-vertex density is one value per vertex of the surface, shape (V,); got "
            f"shape {array.shape}"
        )
    bad = _first_not_positive(array)
    if bad is not None:
        k, count = bad
        raise InvalidDensityError(
            f"the per-vertex density is {array[k]} at vertex {k} ({count} bad values): it "
            "must be finite and positive"
        )
    return array


def _first_not_positive(values: NDArray[np.float64]) -> tuple[int, int] | None:
    """The first index of ``values`` (m,) not finite and positive, and how many are not.

    None when every value is finite and positive.
    """
    bad = ~(np.isfinite(values) & (values > 0))
    if not bad.any():
        return None
    return int(np.flatnonzero(bad)[0]), int(bad.sum())


def triangle_values(
    density: DensityLike, vertices: NDArray[np.float64], faces: NDArray[np.intp]
) -> NDArray[np.float64]:
    """ρ per triangle of a surface (F,), checked.

    A per-vertex field's mean over each triangle's vertices, any other density at each
    triangle's centroid.
    """
    if isinstance(density, np.ndarray):
        values = per_vertex(density)
        if len(values) != len(vertices):
            raise InvalidDensityError(
                f"a per-vertex density needs one value per vertex of the surface: "
                f"{len(values)} values for {len(vertices)} vertices"
            )
        return values[faces].mean(axis=1)
    return evaluate(density, vertices[faces].mean(axis=1))


def core_arguments(
    density: DensityLike, dim: int, quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE
) -> dict[str, Any]:
    """The keyword arguments of ``_core.voronoi`` / ``_core.cvt`` for ``density``.

    ``{}`` without a density (the uniform path, bitwise as before); a polynomial goes as
    coefficients, a callable or sizing field as a function with its quadrature degree.
    """
    if density is None:
        return {}
    if isinstance(quadrature_degree, bool) or quadrature_degree not in QUADRATURE_DEGREES:
        raise InvalidDensityError(
            f"quadrature_degree must be one of {QUADRATURE_DEGREES}, got {quadrature_degree!r}"
        )
    if isinstance(density, Polynomial):
        return {"polynomial": density.coefficients(dim)}
    if isinstance(density, np.ndarray):
        # A surface's per-vertex field: the core takes the array in place of a function.
        return {"function": per_vertex(density)}
    if isinstance(density, SizingField):
        return {"function": density.density(dim), "quadrature_degree": int(quadrature_degree)}
    if callable(density):
        return {"function": density, "quadrature_degree": int(quadrature_degree)}
    raise TypeError(
        "density must be a hcvt.density.Polynomial, a hcvt.density.SizingField, a "
        "vectorised callable rho(points) or (on a surface) a numpy array of values at its "
        f"vertices, got {type(density).__name__}"
    )


def evaluate(density: DensityLike, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """ρ at ``points`` (m, d) for any accepted density, checked finite and positive."""
    dim = points.shape[1]
    if isinstance(density, SizingField):
        values = density.density(dim)(points)
    elif callable(density):
        values = np.asarray(density(points), dtype=np.float64)
    else:
        raise TypeError(f"not a density: {density!r}")
    if values.shape != (len(points),):
        raise InvalidDensityError(
            f"the density must return shape ({len(points)},), got {values.shape}"
        )
    bad = _first_not_positive(values)
    if bad is not None:
        k = bad[0]
        raise InvalidDensityError(
            f"the density is {values[k]} at {points[k].tolist()}: it must be finite and "
            "positive on the domain"
        )
    return values


def grading_slope(
    diagram: Any,
) -> tuple[float, NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """How a diagram's cell size follows its density (Gersho: slope ``-1/(d+2)``).

    Returns the slope of the least-squares line of ``log V_i^(1/d)`` against
    ``log ρ(c_i)`` over the cells off the boundary (``boundary_measure == 0``), with
    ``ρ(c_i)`` (n,), ``V_i^(1/d)`` (n,) and the interior mask (n,).
    """
    if diagram.density is None:
        raise ValueError("the diagram has no density")
    rho = evaluate(diagram.density, diagram.centroid)
    size = diagram.volume ** (1.0 / diagram.domain.dim)
    interior = diagram.boundary_measure == 0
    if interior.sum() < 2:
        raise ValueError("fewer than two interior cells: no slope")
    slope = float(np.polyfit(np.log(rho[interior]), np.log(size[interior]), 1)[0])
    return slope, rho, size, interior


__all__ = [
    "DEFAULT_QUADRATURE_DEGREE",
    "DensityLike",
    "LonLatDensity",
    "Polynomial",
    "SizingField",
    "core_arguments",
    "evaluate",
    "grading_slope",
    "per_vertex",
    "triangle_values",
]
