"""
Cells of a solid: the Stanford bunny
====================================

A 3D domain given only by its closed triangle mesh. 1500 random sites, 40 L-BFGS steps
towards a CVT, and a cut view: the cells behind the median plane, faces coloured by G
(the truncated octahedron of the BCC lattice has G = 0.0785433).
"""

import matplotlib.pyplot as plt

import hcvt
from hcvt.experiments.base import data_dir  # ../shared/data, or $HCVT_DATA
from hcvt.plot import plot_cut

bunny = hcvt.load_domain(data_dir() / "3d" / "bunny.off")

sites = hcvt.initialise(bunny, 1500, seed=0)
result = hcvt.cvt(bunny, sites, max_iter=40)
print(result)

plot_cut(result.diagram, axis=0)
plt.show()
