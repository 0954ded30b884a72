"""GeoJSON contours of a scalar map (RFC 7946: WGS 84 lon/lat), for web maps and Foxglove."""

from __future__ import annotations

import json
from pathlib import Path

from forcemap.host.contours import contour_lines
from forcemap.host.gis.grid import POSITIVE, Layer, MapGrid
from forcemap.host.gis.names import band_attrs
from forcemap.host.outputs import atomic_write


def contour_features(grid: MapGrid, layer: Layer, band: str = "mean") -> dict:
    """A FeatureCollection: one MultiLineString per level of `band` (lines in lon/lat)."""
    from pyproj import Transformer

    z = layer.bands[band]
    attrs = band_attrs(layer, band)
    to_lonlat = Transformer.from_crs(grid.epsg, 4326, always_xy=True)
    features = []
    for level, xy_lines in contour_lines(grid.easting, grid.northing, z):
        if layer.target in POSITIVE and level <= 0.0:
            continue  # never a depth at or above the surface (such cells are blank already)
        lines = []
        for line in xy_lines:
            lon, lat = to_lonlat.transform(line[:, 0], line[:, 1])
            lines.append([[round(a, 8), round(b, 8)] for a, b in zip(lon, lat, strict=True)])
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "MultiLineString", "coordinates": lines},
                "properties": {
                    "target": layer.target,
                    "level": level,
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
