"""Where sites come from: initial samples, the hierarchy, regular CVTs and the baseline.

| module | owns |
|--------|------|
| :mod:`~hcvt.seeding.initialisation` | exactly n sites: random, Halton, Hammersley, lattice |
| :mod:`~hcvt.seeding.hierarchy` | the paper's hierarchical CVT |
| :mod:`~hcvt.seeding.regular` | regular CVTs: posed lattices and defect relaxation |
| :mod:`~hcvt.seeding.baselines` | the global Monte-Carlo method of Lu et al. (2012) |
"""

from hcvt.seeding.baselines import MonteCarloResult, global_monte_carlo
from hcvt.seeding.hierarchy import HierarchicalResult, hierarchical_cvt
from hcvt.seeding.initialisation import LatticeResult, initialise
from hcvt.seeding.regular import RegularResult, defects, regular_cvt

__all__ = [
    "HierarchicalResult",
    "LatticeResult",
    "MonteCarloResult",
    "RegularResult",
    "defects",
    "global_monte_carlo",
    "hierarchical_cvt",
    "initialise",
    "regular_cvt",
]
