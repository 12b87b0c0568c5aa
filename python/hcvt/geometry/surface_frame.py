"""The frame of a triangle surface: the solid's frame, with units counted for cells of dimension 2.

A surface is moved and scaled into the core's unit frame exactly as a solid is
(:class:`hcvt.geometry.frame.Frame`: positions are 3D); its cells have dimension 2, so a
result of unit ``L^(a·d + b)`` is counted with ``d = 2`` (areas ``L²``, energies and
second moments ``L⁴``, arc lengths ``L``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from numpy.typing import ArrayLike

from hcvt.errors import InvalidDensityError
from hcvt.geometry.frame import Frame


@dataclass(frozen=True, eq=False)
class SurfaceFrame(Frame):
    """``x = scale · x' + centre`` (3D) for cells of dimension 2."""

    @classmethod
    def fit_surface(cls, vertices: ArrayLike) -> SurfaceFrame:
        """The frame :meth:`Frame.fit` gives the surface's vertices (V, 3)."""
        frame = Frame.fit(vertices)
        return cls(frame.centre, frame.scale)

    @property
    def dim(self) -> int:
        """2: the dimension of the cells, which every unit's power counts."""
        return 2

    def density_to_core(self, density: Any) -> Any:
        """No density on a surface yet: None passes, anything else raises."""
        if density is None:
            return None
        raise InvalidDensityError(
            "densities on a surface are not implemented yet; pass density=None"
        )


__all__ = ["SurfaceFrame"]
