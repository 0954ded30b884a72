"""Maps that leave forcemap: grids in the survey's UTM zone written as GeoTIFF, CF NetCDF and GeoJSON contours.

Needs the optional extra `forcemap[gis]` (rasterio, pyproj, xarray, netCDF4); `need_gis` says so in one line.
"""

from __future__ import annotations

import importlib.util

from forcemap.host.errors import CliError
from forcemap.host.extras import install_hint

GIS_MODULES = ("rasterio", "pyproj", "xarray", "netCDF4")


def need_gis(what: str = "maps for GIS") -> None:
    """A one-line error naming the extra when one of its packages is missing."""
    missing = [m for m in GIS_MODULES if importlib.util.find_spec(m) is None]
    if missing:
        raise CliError(f"{what} need {', '.join(missing)}: {install_hint('gis')}")
