"""Domains and what they are made of: polygons with holes and closed triangle meshes.

| module | owns |
|--------|------|
| :mod:`~hcvt.geometry.domain` | :class:`Domain`: validation, repair, bounds, moments, inside test |
| :mod:`~hcvt.geometry.repair` | triangle meshes: defects found and named, repaired on request |
| :mod:`~hcvt.geometry.shapes` | the built-in shapes (square, star, ball) |
"""

from hcvt.geometry.domain import Domain, RepairReport

__all__ = ["Domain", "RepairReport"]
