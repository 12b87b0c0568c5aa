"""The frame of a triangle surface: the solid's frame, with units counted for cells of dimension 2.

A surface is moved and scaled into the core's unit frame exactly as a solid is
(:class:`hcvt.geometry.frame.Frame`: positions are 3D); its cells have dimension 2, so a
result of unit ``L^(a·d + b)`` is counted with ``d = 2`` (areas ``L²``, energies and
second moments ``L⁴``, arc lengths ``L``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

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
        """``density`` in the frame, as a solid's frame has it; an array passes as it is.

        A callable is evaluated at the points mapped back and a polynomial expanded
        (:meth:`Frame.density_to_core`); a per-vertex field's values do not depend on the
        frame.
        """
        if isinstance(density, np.ndarray):
            return density
        return super().density_to_core(density)


__all__ = ["SurfaceFrame"]
