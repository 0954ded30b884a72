"""What each band is called, in CF terms: variable names, standard names, units and long names."""

from __future__ import annotations

# target (scalar) or vector family -> CF standard name of the mean, per band
SCALAR_STANDARD_NAMES = {
    "depth": ("sea_floor_depth_below_sea_surface", "m"),
    "water_temp": ("sea_water_temperature", "degC"),
}
VECTOR_STANDARD_NAMES = {
    "current": {
        "east": "eastward_sea_water_velocity",
        "north": "northward_sea_water_velocity",
        "speed": "sea_water_speed",
        "dir": "direction_of_sea_water_velocity",
    },
    "wind": {
        "east": "eastward_wind",
        "north": "northward_wind",
        "speed": "wind_speed",
        "dir": "wind_from_direction",
    },
}
VECTOR_LONG_NAMES = {
    "east": "{f} velocity, east component",
    "north": "{f} velocity, north component",
    "speed": "{f} speed",
    "dir": "{f} direction ({conv}, degrees clockwise from true north)",
}


def band_attrs(layer, band: str) -> dict[str, str]:
    """CF attributes of one band of a layer (a `_sd` band is the standard error of its mean)."""
    base, sd = (band[:-3], True) if band.endswith("_sd") or band == "sd" else (band, False)
    if band == "sd":
        base = "mean"
    if layer.vector is None:
        std, units = SCALAR_STANDARD_NAMES.get(layer.target, (None, ""))
        long = layer.target.replace("_", " ")
    else:
        std = VECTOR_STANDARD_NAMES.get(layer.vector, {}).get(base)
        units = "degree" if base == "dir" else "m s-1"
        conv = "where it blows from" if layer.vector == "wind" else "where it flows to"
        long = VECTOR_LONG_NAMES[base].format(f=layer.vector, conv=conv)
    attrs = {"long_name": f"standard deviation of the model's {long}" if sd else f"model {long}"}
    if std:
        attrs["standard_name"] = f"{std} standard_error" if sd else std
    if units:
        attrs["units"] = units
    return attrs


def variable_name(layer, band: str) -> str:
    """The NetCDF variable of a band: `depth`, `depth_sd`, `current_east`, `wind_speed_sd`, ..."""
    if layer.vector is None:
        return layer.target if band == "mean" else f"{layer.target}_sd"
    return f"{layer.prefix}_{band}"
