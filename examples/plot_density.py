"""
A graded CVT
============

A density ρ = 1 + 99 x² that grows 100 times across the unit square: a CVT's cells follow
ρ^(-1/4) (Gersho), small on the right. G stays the geometric regularity of each cell,
so a graded CVT is as blue as a uniform one.
"""

import matplotlib.pyplot as plt

import hcvt
from hcvt.plot import plot_cells

square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
rho = hcvt.Polynomial.parse("1 + 99*x^2")
sites = hcvt.initialise(square, 1500, seed=0, density=rho)
result = hcvt.cvt(square, sites, method="newton", density=rho)
print(result)

plot_cells(result.diagram, title=f"ρ = 1 + 99 x², mean G {result.mean_G:.5f}")
plt.show()
