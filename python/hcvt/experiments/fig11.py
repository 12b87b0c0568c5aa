"""Figure 11: standard against hierarchical CVTs of 50k, 80k and 100k sites in real meshes.

Per mesh (the paper's: the bunny at 50k, the kitten at 80k, Armadillo at 100k; Table 7
names them): random sites + CVT, hierarchical from random sites, hierarchical from a
lattice (s = 1). The paper shows pictures only; we add mean G. Newton to our default rule
(the paper's rule is not scale-free; in these meshes' units it holds early) for every run.
``quick``: 5,000 sites each.
"""

from __future__ import annotations

from hcvt.experiments.base import Config, Experiment
from hcvt.experiments.paper import PAPER
from hcvt.seeding.hierarchy import max_subdivisions

METHODS = (
    ("random + Newton", "newton", "random"),
    ("hierarchical, random", "hierarchical", "random"),
    ("hierarchical, lattice", "hierarchical", "lattice"),
)


def subdivisions(method: str, init: str, n: int) -> int | None:
    """The paper's choices: the most from random sites, one from a lattice."""
    if method != "hierarchical":
        return None
    return max_subdivisions(n, 3) if init == "random" else 1


def experiments(quick: bool) -> list[Experiment]:
    """Figure 11, one experiment per mesh (``fig11_bunny`` …) and all of them as ``fig11``."""
    made = []
    for shape, n in PAPER["fig11"].items():
        n = 5000 if quick else n
        name = f"fig11_{shape.split('.')[0]}"
        configs = tuple(
            Config(
                name,
                f"{shape} {n}: {label}" + ("" if s is None else f", s={s}"),
                shape,
                n,
                method,
                init,
                s,
                keep_sites=True,
                optimiser="newton",
                rule="gap",
            )
            for label, method, init in METHODS
            for s in [subdivisions(method, init, n)]
        )
        title = f"{shape}, n = {n}: standard against hierarchical CVTs (paper Figure 11)"
        made.append(Experiment(name, title, configs, 3, ("cuts",)))
    whole = Experiment(
        "fig11",
        "Standard against hierarchical CVTs in real meshes (paper Figure 11)",
        tuple(c for e in made for c in e.configs),
        3,
        (),
    )
    return [whole, *made]
