"""GeoJSON contours of a scalar map (RFC 7946: WGS 84 lon/lat), for web maps and Foxglove."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from forcemap.host.gis.grid import Layer, MapGrid
from forcemap.host.gis.names import band_attrs
from forcemap.host.outputs import atomic_write

N_LEVELS = 10


def levels(values: np.ndarray, n: int = N_LEVELS) -> np.ndarray:
    """Round contour levels strictly inside the mapped range (matplotlib's tick rule)."""
    from matplotlib.ticker import MaxNLocator

    lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
    if not hi > lo:
        return np.array([])
    ticks = MaxNLocator(n).tick_values(lo, hi)
    return ticks[(ticks > lo) & (ticks < hi)]


def contour_features(grid: MapGrid, layer: Layer, band: str = "mean") -> dict:
    """A FeatureCollection: one MultiLineString per level of `band` (lines in lon/lat)."""
    import contourpy
    from pyproj import Transformer

    z = layer.bands[band]
    attrs = band_attrs(layer, band)
    gen = contourpy.contour_generator(grid.easting, grid.northing, np.ma.masked_invalid(z))
    to_lonlat = Transformer.from_crs(grid.epsg, 4326, always_xy=True)
    features = []
    for level in levels(z) if np.isfinite(z).any() else []:
        lines = []
        for line in gen.lines(float(level)):
            if len(line) < 2:
                continue
            lon, lat = to_lonlat.transform(line[:, 0], line[:, 1])
            lines.append([[round(a, 8), round(b, 8)] for a, b in zip(lon, lat, strict=True)])
        if lines:
            features.append(
                {
                    "type": "Feature",
                    "geometry": {"type": "MultiLineString", "coordinates": lines},
                    "properties": {
                        "target": layer.target,
                        "level": float(level),
                        "units": attrs.get("units", ""),
                        "model_terms": " + ".join(layer.terms),
                    },
                }
            )
    return {"type": "FeatureCollection", "features": features}


def write_contours(grid: MapGrid, layer: Layer, path: str | Path) -> Path:
    path = Path(path)
    with atomic_write(path) as f:
        json.dump(contour_features(grid, layer), f)
    return path
