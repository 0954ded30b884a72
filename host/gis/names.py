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


# a depth layer's surface bands (host/gis/surface.py): the CUBE-like surface and what supports it
_DEPTH = "sea_floor_depth_below_sea_surface"
SURFACE_ATTRS: dict[str, dict[str, str]] = {
    "surface": {
        "standard_name": _DEPTH, "units": "m",
        "long_name": "depth surface: at each cell the depth hypothesis most soundings support (each "
        "sounding's TVU propagated to the cell, several hypotheses kept where they disagree; CUBE, "
        "Calder & Mayer 2003); empty where no kept sounding reaches the cell",
    },
    "surface_sd": {
        "standard_name": f"{_DEPTH} standard_error", "units": "m",
        "long_name": "1-sd vertical uncertainty of the depth surface: a sounding's total vertical "
        "uncertainty at the cell (not reduced by averaging: the soundings' errors share their sources)",
    },
    "surface_tvu": {
        "units": "m",
        "long_name": "total vertical uncertainty of the depth surface at the 95 % confidence level "
        "(IHO S-44 6th ed.: 1.96 x surface_sd)",
    },
    "surface_order": {
        "long_name": "the strictest IHO S-44 (6th ed.) order whose maximum allowable TVU, "
        "sqrt(a^2 + (b d)^2), the cell's TVU meets",
        "flag_values": "0 1 2 3 4",
        "flag_meanings": "no_order exclusive_order special_order order_1a_1b order_2",
    },
    "surface_hypotheses": {
        "units": "1",
        "long_name": "depth hypotheses kept at the cell (more than one: its soundings disagree)",
    },
    "surface_soundings": {  # CF's number_of_observations modifier is deprecated: no standard name
        "units": "1",
        "long_name": "soundings that reached the cell",
    },
    "surface_support": {
        "units": "1",
        "long_name": "share of the cell's soundings in the chosen hypothesis",
    },
}  # fmt: skip


def _split(layer, band: str) -> tuple[str, str]:
    """(the band's quantity, its kind: "value", "sd" the predictive sd, "mean_sd" the sd of the mean)."""
    scalar = layer.vector is None
    if band == "mean_sd" or band.endswith("_mean_sd"):
        return ("mean" if scalar else band[: -len("_mean_sd")]), "mean_sd"
    if band == "sd" or band.endswith("_sd"):
        return ("mean" if band == "sd" else band[:-3]), "sd"
    return band, "value"


# a current related to a reference current (host/workbench/terms/reference_maps.py): each place's relation
# to its station, flood and ebb (`ebb_*`), with their posterior sd
RELATION_ATTRS: dict[str, dict[str, str]] = {
    "ratio": {"units": "1", "long_name": "the flood's speed at the place over its reference station's "
              "(a subordinate station's speed ratio)"},
    "offset": {"units": "s", "long_name": "how much later than its reference station the place's "
               "flood runs (negative: earlier; a subordinate station's time offset)"},
}  # fmt: skip
for _b, _a in list(RELATION_ATTRS.items()):
    RELATION_ATTRS[f"{_b}_sd"] = {**_a, "long_name": f"posterior standard deviation of: {_a['long_name']}"}
for _b, _a in list(RELATION_ATTRS.items()):
    RELATION_ATTRS[f"ebb_{_b}"] = {**_a, "long_name": _a["long_name"].replace("flood", "ebb")}


def band_attrs(layer, band: str) -> dict[str, str]:
    """CF attributes of one band of a layer: a `_sd` band is the predictive standard deviation (what a new
    measurement would differ from the mean by), a `mean_sd` band the standard deviation of the mean alone."""
    if layer.vector is None and band in SURFACE_ATTRS:
        return dict(SURFACE_ATTRS[band])
    if layer.vector is not None and band in RELATION_ATTRS:
        return dict(RELATION_ATTRS[band])
    base, kind = _split(layer, band)
    if layer.vector is None:
        std, units = SCALAR_STANDARD_NAMES.get(layer.target, (None, ""))
        long = layer.target.replace("_", " ")
    else:
        std = VECTOR_STANDARD_NAMES.get(layer.vector, {}).get(base)
        units = "degree" if base == "dir" else "m s-1"
        conv = "where it blows from" if layer.vector == "wind" else "where it flows to"
        long = VECTOR_LONG_NAMES[base].format(f=layer.vector, conv=conv)
    long_names = {
        "value": f"model {long}",
        "sd": f"predictive standard deviation of the {long}: what a new measurement would differ from "
        "the model's mean by (latent and noise variance, scaled to cover 95 % of blocked-CV held-out "
        "samples at 1.96 sd)",
        "mean_sd": f"standard deviation of the model's mean {long} (of the mean only, not of a new "
        "measurement)",
    }
    attrs = {"long_name": long_names[kind]}
    if std and kind != "mean_sd":
        attrs["standard_name"] = f"{std} standard_error" if kind == "sd" else std
    if units:
        attrs["units"] = units
    return attrs


def variable_name(layer, band: str) -> str:
    """The NetCDF variable of a band: `depth`, `depth_sd`, `depth_mean_sd`, `current_east`, `wind_speed_sd`..."""
    if layer.vector is None:
        return layer.target if band == "mean" else f"{layer.target}_{band}"
    return f"{layer.prefix}_{band}"
