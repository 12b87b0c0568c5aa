"""
Staten Island in its own CRS, with GeoPandas
============================================

A borough outline in NAD83 / New York Long Island State Plane (US feet, EPSG:2263), read
as a GeoDataFrame, a CVT of 800 sites, and the cells back as a GeoDataFrame in the same
CRS (row i the cell of site i), drawn by GeoPandas coloured by G.
"""

import geopandas as gpd
import matplotlib.pyplot as plt

import hcvt
from hcvt.experiments.base import data_dir  # ../shared/data, or $HCVT_DATA

path = data_dir() / "2d" / "nybb_staten_island_main.geojson"
# The file declares no CRS (GDAL would assume lon/lat): say what the numbers are.
island = gpd.read_file(path).set_crs("EPSG:2263", allow_override=True)

domain = hcvt.load_domain(island)
result = hcvt.cvt(domain, hcvt.initialise(domain, 800, seed=0), method="newton")
cells = result.diagram.to_geopandas()
print(cells.crs, len(cells), f"{cells.area.sum() / island.area.iloc[0]:.15f}")

ax = cells.plot(column="G", cmap="RdYlBu_r", edgecolor="k", linewidth=0.2, figsize=(7, 7))
ax.set_title(f"{len(cells)} cells, mean G {result.mean_G:.5f} ({cells.crs})")
ax.set_axis_off()
plt.show()
