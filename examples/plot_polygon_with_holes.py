"""
Clipped cells of a polygon with holes
=====================================

The letter B of DejaVu Sans (two holes, curved outline): the exact clipped Voronoi
diagram of 600 Halton sites, then the same sites after a CVT. Cell areas sum to the
glyph's area to round-off.
"""

import matplotlib.pyplot as plt

import hcvt
from hcvt.experiments.base import data_dir  # ../shared/data, or $HCVT_DATA
from hcvt.plot import plot_cells

glyph = hcvt.load_domain(data_dir() / "2d" / "dejavu_sans_B.geojson")

sites = hcvt.initialise(glyph, 600, method="halton", seed=0)
before = hcvt.voronoi(glyph, sites)
after = hcvt.cvt(glyph, sites, method="newton").diagram
print(f"area {glyph.volume:.6f}, cells {before.volume.sum():.6f}")

fig, axes = plt.subplots(1, 2, figsize=(10, 5))
plot_cells(before, axes[0], colorbar=False, title=f"Halton sites, mean G {before.mean_G:.5f}")
plot_cells(after, axes[1], title=f"CVT, mean G {after.mean_G:.5f}")
plt.show()
