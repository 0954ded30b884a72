"""NetCDF (CF-1.8): every target in one `xarray.Dataset` on the UTM grid, with 2-D lat/lon auxiliary
coordinates, the CRS as a grid mapping, each standard deviation an ancillary variable of its mean, and the
survey's time span and the model terms in the attributes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from forcemap.host.gis.grid import MapGrid
from forcemap.host.gis.names import band_attrs, variable_name
from forcemap.host.outputs import atomic_path

GRID_MAPPING = "crs"


def to_dataset(grid: MapGrid):
    """The grid and its layers as an `xarray.Dataset` (CF-1.8 attributes)."""
    import xarray as xr
    from pyproj import CRS

    coords = {
        "x": ("x", grid.easting, _attrs("projection_x_coordinate", "m", "easting")),
        "y": ("y", grid.northing, _attrs("projection_y_coordinate", "m", "northing")),
        "lat": (("y", "x"), grid.lat, _attrs("latitude", "degrees_north", "latitude")),
        "lon": (("y", "x"), grid.lon, _attrs("longitude", "degrees_east", "longitude")),
        "time": ((), grid.time, _time_attrs(grid.at is not None)),
    }
    data = {
        GRID_MAPPING: ((), np.int32(0), CRS.from_epsg(grid.epsg).to_cf()),
        "time_bnds": (("nv",), np.asarray(grid.time_span, float)),
    }
    terms = []
    for layer in grid.layers.values():
        terms.append(f"{layer.target}: {' + '.join(layer.terms)}")
        for band, values in layer.bands.items():
            attrs = band_attrs(layer, band)
            attrs["grid_mapping"] = GRID_MAPPING
            attrs["forcemap_model_terms"] = " + ".join(layer.terms)
            if layer.datum:
                attrs["vertical_datum"] = layer.datum
            if layer.calibration is not None:
                attrs["forcemap_coverage95"] = layer.calibration.line()
            if layer.notes:
                attrs["forcemap_notes"] = "; ".join(layer.notes)
            if "flag_values" in attrs:  # CF flags: the values as the variable's own type
                attrs["flag_values"] = np.array(attrs["flag_values"].split(), float)
            if band == "surface":
                sds = [variable_name(layer, b) for b in layer.bands if b.startswith("surface_")]
                attrs["ancillary_variables"] = " ".join(sds)
            elif band.startswith("surface_"):
                pass
            elif not (band == "sd" or band.endswith("_sd")):
                sds = ["sd", "mean_sd"] if band == "mean" else [f"{band}_sd", f"{band}_mean_sd"]
                sds = [variable_name(layer, sd) for sd in sds if sd in layer.bands]
                if sds:
                    attrs["ancillary_variables"] = " ".join(sds)
            data[variable_name(layer, band)] = (("y", "x"), values, attrs)
    start, end = grid.time_coverage()
    datums = [f"{lay.target}: {lay.datum}" for lay in grid.layers.values() if lay.datum]
    ds = xr.Dataset(data, coords=coords)
    ds.attrs = {
        "Conventions": "CF-1.8",
        "title": "forcemap survey maps",
        "source": "forcemap: Gaussian-process maps of a small surface vehicle's survey",
        "time_coverage_start": start,
        "time_coverage_end": end,
        "forcemap_map_time": grid.time_iso(),
        "model_terms": "; ".join(terms),
        "comment": (
            f"cells farther than {grid.max_distance:g} m from every sample are missing, and so are a "
            "target's cells beyond its cross-validation's reach, with a predictive sd above the measured "
            "values' own, or a depth at or above the surface (see each variable's forcemap_notes); "
            "covariates other than position are held at the survey's typical values, time at the "
            f"variable time ({grid.time_iso()}); "
            "*_sd variables are predictive standard deviations (a new measurement), *_mean_sd those of the "
            "mean alone"
        ),
        "geospatial_crs": f"EPSG:{grid.epsg} ({grid.zone_name})",
        "resolution_m": float(grid.resolution),
    }
    if datums:
        ds.attrs["vertical_datum"] = "; ".join(datums)
    return ds


def write_netcdf(grid: MapGrid, path: str | Path) -> Path:
    """Write `to_dataset(grid)` (netCDF4 engine, compressed); returns the path."""
    path = Path(path)
    ds = to_dataset(grid)
    enc = {v: {"zlib": True, "complevel": 1, "_FillValue": np.nan} for v in ds.data_vars}
    enc[GRID_MAPPING] = {"_FillValue": None}
    enc["time_bnds"] = {"_FillValue": None}
    for c in ("x", "y", "lat", "lon", "time"):
        enc[c] = {"_FillValue": None}
    with atomic_path(path) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4", encoding=enc)
    return path


def _attrs(standard_name: str, units: str, long_name: str) -> dict[str, str]:
    return {"standard_name": standard_name, "units": units, "long_name": long_name}


def _time_attrs(asked: bool) -> dict[str, str]:
    return {
        "standard_name": "time",
        "long_name": "the time the maps are evaluated at"
        + (" (asked for: --at)" if asked else " (the survey's mid-time, its median sample)"),
        "units": "seconds since 1970-01-01 00:00:00Z",
        "calendar": "standard",
        "bounds": "time_bnds",
    }
