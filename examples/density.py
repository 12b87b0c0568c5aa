"""A graded CVT: cells follow a density ρ that varies 100x across the unit square.

Writes ``docs/results/density_square.png`` (cells coloured by size, and cell size against
ρ with Gersho's slope -1/4) and ``docs/results/density_ball.png`` (the same plot for a
ball, slope -1/5), and prints the fitted slopes.

    OPENBLAS_NUM_THREADS=1 python examples/density.py
"""

from __future__ import annotations

from pathlib import Path

import hcvt
from hcvt.density import Polynomial
from hcvt.plot import grading_figure

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
OUT = ROOT / "docs" / "results"


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    rho = Polynomial.parse("1 + 99*x^2")  # 1 at x = 0 to 100 at x = 1
    sites = hcvt.initialise(square, 3000, seed=0, density=rho)
    res = hcvt.cvt(square, sites, density=rho)
    slope = grading_figure(res.diagram, OUT / "density_square.png")
    print(
        f"square, {res.diagram.n} sites, rho = {rho!r}: {res.stop_reason} after "
        f"{res.iterations} iterations; size ~ rho^{slope:.4f} (Gersho -0.25)"
    )
    ball = hcvt.load_domain(DATA / "3d" / "sphere.ply")
    rho3 = Polynomial.parse("30.25 + 49.5*x + 20.25*x^2", dim=3)  # (1 + 4.5 (x + 1))²
    sites = hcvt.initialise(ball, 5000, seed=0, density=rho3)
    res = hcvt.cvt(ball, sites, density=rho3)
    slope = grading_figure(res.diagram, OUT / "density_ball.png")
    print(
        f"ball, {res.diagram.n} sites, rho = {rho3!r}: {res.stop_reason} after "
        f"{res.iterations} iterations; size ~ rho^{slope:.4f} (Gersho -0.2)"
    )


if __name__ == "__main__":
    main()
