"""Built-in domains: the paper's shapes, so that examples run without input files.

| name          | shape                                             | measure        |
|---------------|---------------------------------------------------|----------------|
| ``square``    | the paper's 20 x 20 square (Table 4 energies)     | area 400       |
| ``star``      | a regular five-branch star (pentagram outline)    | area 117.5     |
| ``unit-square`` | [0, 1]^2                                        | area 1         |
| ``ball``      | the paper's ball: icosphere, 642 vertices, 1,280 triangles | volume 1.42 |
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hcvt.geometry.domain import Domain
from hcvt.lazy import load

# The paper's star: its Table 5 optimal energy 0.221 at n = 10025 gives area ≈ 117.5.
STAR_AREA = 117.5
# Pentagram outline: inner radius for concave vertices collinear with the tips.
STAR_INNER_RATIO = np.sin(np.radians(18)) / np.sin(np.radians(126))


def square() -> Domain:
    """The paper's 20 x 20 square, corner at the origin."""
    return Domain.from_polygon([(0, 0), (20, 0), (20, 20), (0, 20)])


def unit_square() -> Domain:
    """The unit square [0, 1]^2."""
    return Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])


# The paper's ball: its Table 6 energies give volume ≈ 1.42; it has a 1k-triangle mesh.
BALL_VOLUME = 1.42


def ball(volume: float = BALL_VOLUME) -> Domain:
    """The paper's ball: an icosphere of 642 vertices and 1,280 triangles, of this volume.

    trimesh's icosphere at subdivision 3, centred at the origin, scaled so that the
    polyhedron (not the sphere it approximates) has volume ``volume``.
    """
    mesh = load("trimesh").creation.icosphere(subdivisions=3)
    scale = (volume / mesh.volume) ** (1.0 / 3.0)
    return Domain.from_mesh(np.asarray(mesh.vertices) * scale, np.asarray(mesh.faces))


def star(area: float = STAR_AREA) -> Domain:
    """A regular pentagram outline of the given area, centred at the origin, tip up."""
    angles = np.pi / 2 + np.arange(10) * np.pi / 5
    radii = np.where(np.arange(10) % 2 == 0, 1.0, STAR_INNER_RATIO)
    ring = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
    unit_area = 0.5 * abs(
        np.dot(ring[:, 0], np.roll(ring[:, 1], -1)) - np.dot(ring[:, 1], np.roll(ring[:, 0], -1))
    )
    return Domain.from_polygon(ring * np.sqrt(area / unit_area))


BUILTIN: dict[str, Callable[[], Domain]] = {
    "ball": ball,
    "square": square,
    "star": star,
    "unit-square": unit_square,
}


def builtin_domain(name: str) -> Domain:
    """The built-in domain called ``name`` (see the module table)."""
    try:
        return BUILTIN[name]()
    except KeyError:
        known = ", ".join(sorted(BUILTIN))
        raise ValueError(f"unknown built-in shape {name!r}; known: {known}") from None
