"""Third-party packages imported on first use, in one place.

``import hcvt`` stays fast (tests/test_package.py: no matplotlib, trimesh, dask, rich):
the packages below are imported only by the functions that need them, through
:func:`load`, which also says how to install the optional ones.
"""

from __future__ import annotations

import importlib
from types import ModuleType

#: Packages hcvt imports lazily, and the extra that installs each optional one.
LAZY = {
    "trimesh": None,  # mesh files (slow to import, ~0.5 s)
    "manifold3d": None,  # uniting overlapping shells when repairing a mesh
    "rich.progress": None,  # progress bars
    "dask.distributed": None,  # scale-out
    "matplotlib": None,  # pictures: hcvt.plot, hcvt.draw (Jupyter)
    "matplotlib.cm": None,
    "matplotlib.collections": None,
    "matplotlib.colors": None,
    "matplotlib.figure": None,
    "mpl_toolkits.mplot3d.art3d": None,
    "meshio": None,  # mesh files trimesh does not write: hcvt run --surface --out .vtu
    "pyvista": "viz",  # interactive viewing: Diagram.to_pyvista()
    "pyproj": "geo",  # coordinate reference systems of GIS input: Domain.crs
    "geopandas": "geo",  # GIS files and GeoDataFrames: load_domain, Diagram.to_geopandas()
    "pandas": "geo",  # the index of Diagram.to_geopandas()
    "xarray": "mpas",  # MPAS mesh files of spherical diagrams: hcvt.write_mpas (netCDF4)
}


def load(name: str) -> ModuleType:
    """Import ``name`` (one of :data:`LAZY`) now.

    Raises
    ------
    ModuleNotFoundError
        Not installed; the message names the extra that installs it.
    """
    if name not in LAZY:
        raise ValueError(f"{name!r} is not one of hcvt's lazily imported packages")
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as error:
        extra = LAZY[name]
        hint = f"pip install 'hcvt[{extra}]'" if extra else f"pip install {name.split('.')[0]}"
        raise ModuleNotFoundError(f"{name} is needed here: {hint}") from error
