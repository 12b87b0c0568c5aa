"""Shared fixtures."""

from __future__ import annotations

import os

import pytest

# Figures in tests go to files; hcvt itself leaves the backend to the user.
os.environ.setdefault("MPLBACKEND", "Agg")

import hcvt


@pytest.fixture(scope="session")
def square_with_holes() -> hcvt.Domain:
    """A 4 x 4 square with a square hole and a triangular hole."""
    return hcvt.Domain.from_polygon(
        [(0, 0), (4, 0), (4, 4), (0, 4)],
        holes=[[(1, 1), (1, 2), (2, 2), (2, 1)], [(2.5, 2.5), (3.5, 2.5), (3, 3.5)]],
    )
