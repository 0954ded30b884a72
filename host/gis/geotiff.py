"""GeoTIFF: one Cloud Optimized GeoTIFF per target, its bands named, CRS and geotransform set, NaN nodata."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from forcemap.host.gis.grid import Layer, MapGrid
from forcemap.host.gis.names import band_attrs
from forcemap.host.outputs import atomic_path

# GDAL's COG driver: 512-pixel tiles, overviews, DEFLATE with the floating-point predictor. The values are
# float64: float32 would round a direction near 360 deg by 3e-5, more than a map's values are checked to
COG_PROFILE = {
    "driver": "COG",
    "dtype": "float64",
    "nodata": np.nan,
    "compress": "deflate",
    "predictor": 3,
    "blocksize": 512,
}


def write_geotiff(grid: MapGrid, layer: Layer, path: str | Path) -> Path:
    """Write one target's bands (in the order of `layer.bands`) as a COG; returns the path."""
    import rasterio
    from rasterio.transform import from_origin

    path = Path(path)
    names = list(layer.bands)
    profile = dict(
        COG_PROFILE,
        width=grid.nx,
        height=grid.ny,
        count=len(names),
        crs=f"EPSG:{grid.epsg}",
        transform=from_origin(grid.x0, grid.y1, grid.resolution, grid.resolution),
    )
    with atomic_path(path) as tmp, rasterio.open(tmp, "w", **profile) as dst:
        dst.write(np.stack([layer.bands[n] for n in names]))
        dst.update_tags(
            target=layer.target,
            model_terms=" + ".join(layer.terms),
            mask_distance_m=f"{grid.max_distance:g}",
            time_coverage="/".join(grid.time_coverage()),
            time=grid.time_iso(),
            **({"coverage95": layer.calibration.line()} if layer.calibration is not None else {}),
            **({"notes": "; ".join(layer.notes)} if layer.notes else {}),
        )
        if layer.datum:
            dst.update_tags(vertical_datum=layer.datum)
        for i, name in enumerate(names, 1):
            dst.set_band_description(i, name)
            attrs = band_attrs(layer, name)
            dst.update_tags(i, **attrs)
            if "units" in attrs:
                dst.set_band_unit(i, attrs["units"])
    return path
