"""
A regular CVT of a star
=======================

The README's first command, ``hcvt run star -n 2000 --plot star.png``, in Python: 2000
random sites in the paper's five-pointed star (area 117.5) moved to a centroidal Voronoi
tessellation by Newton's method, cells coloured by G from blue (the regular hexagon,
G = 0.0801875) to red.
"""

import matplotlib.pyplot as plt

import hcvt
from hcvt.geometry.shapes import star
from hcvt.plot import plot_cells

domain = star()
sites = hcvt.initialise(domain, 2000, seed=0)
result = hcvt.cvt(domain, sites, method="newton")
print(result)

plot_cells(result.diagram)
plt.show()
