"""The paper's numbers, in one table: what every experiment sets our values beside.

``PAPER[name]`` holds the values of the paper's table ``name``, keyed by its rows: mean G
and CVT energy per configuration (Tables 2–6; energies at the paper's site count), seconds
(Tables 7 and 8). Tables 4 and 5 are keyed by our row labels; the shapes are the paper's at
the paper's size (:mod:`hcvt.geometry.shapes`), so energies compare without scaling.
"""

from __future__ import annotations

from typing import Any

PAPER: dict[str, Any] = {
    # Square, n = 2560, s = 4, random initialisation: mean G of each level, coarsest first.
    "table2": (0.08458, 0.08246, 0.08154, 0.08099, 0.08066),
    # Square, n = 10000, random initialisation: mean G for s = 0 … 4.
    "table3": (0.08079, 0.08063, 0.08060, 0.08056, 0.08054),
    # Square 20 x 20, n = 1033: (mean G, energy).
    "table4": {
        "(a) random + L-BFGS": (0.08101, 25.140),
        "(b) Hammersley + L-BFGS": (0.08107, 25.160),
        "(c) global Monte-Carlo": (0.08075, 25.041),
        "(d) hierarchical, random, s=4": (0.08086, 25.082),
        "(e) hierarchical, lattice, s=1": (0.08077, 25.045),
        "(f) hexagonal lattice": (0.08066, 25.002),
    },
    # Star of area 117.5, n = 10025: (mean G, energy).
    "table5": {
        "(a) random + L-BFGS": (0.08089, 0.2234),
        "(c) Hammersley + L-BFGS": (0.08074, 0.2229),
        "(e) hierarchical, random, s=5": (0.08068, 0.2227),
        "(g) hierarchical, lattice, s=1": (0.08054, 0.2222),
        "(i) hexagonal lattice": (0.08049, 0.2220),
    },
    # Ball of volume 1.42, by n: (mean G, energy) of random + L-BFGS, Hammersley + L-BFGS,
    # hierarchical from random sites, hierarchical from a lattice.
    "table6": {
        1000: ((0.08025, 4.324e-3), (0.08025, 4.325e-3), (0.08022, 4.324e-3), (0.08022, 4.325e-3)),
        5000: ((0.07980, 1.471e-3), (0.07976, 1.470e-3), (0.07975, 1.470e-3), (0.07965, 1.468e-3)),
    },
    # Seconds of one clipped Voronoi diagram of random sites, by (shape, n).
    "table7": {
        ("ball", 1000): 0.55,
        ("homer.obj", 35000): 28.66,
        ("bunny.off", 50000): 30.06,
        ("kitten.obj", 80000): 54.57,
        ("armadillo.obj", 100000): 103.06,
    },
    # CVT seconds by (shape, n): (standard, hierarchical, the hierarchy's subdivisions).
    "table8": {
        ("square", 1000): (2.84, 2.16, 4),
        ("square", 5000): (10.85, 9.50, 4),
        ("star", 2000): (3.56, 4.91, 4),
        ("star", 10000): (26.94, 26.97, 4),
        ("ball", 1000): (521.86, 205.82, 2),
        ("ball", 5000): (1484.69, 665.01, 3),
        ("homer.obj", 50000): (15720.0, 7860.0, 4),
    },
    # Figure 1: Homer, hierarchical from random sites, levels of 546, 4,375 and 35,000 cells
    # (pictures only). Figure 11: CVTs of 50k, 80k and 100k sites (pictures only), by mesh.
    "fig1": ("homer.obj", 35000, 2),
    "fig11": {"bunny.off": 50000, "kitten.obj": 80000, "armadillo.obj": 100000},
}
