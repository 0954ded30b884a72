"""JSON schemas (MCAP ``jsonschema`` encoding) for every topic the pipeline writes."""

from __future__ import annotations

import json
from typing import Any

NUM = {"type": ["number", "null"]}
INT = {"type": ["integer", "null"]}
STR = {"type": ["string", "null"]}
BOOL = {"type": "boolean"}


def _obj(
    title: str,
    props: dict[str, Any],
    required: list[str] | None = None,
    extra: bool = False,
    description: str = "",
) -> dict[str, Any]:
    d: dict[str, Any] = {"title": title, "type": "object", "properties": props}
    if description:
        d["description"] = description
    if required:
        d["required"] = required
    if not extra:
        d["additionalProperties"] = False
    return d


SAMPLE_COLUMNS: tuple[str, ...] = (
    "t", "lat", "lon", "heading", "yaw_rate", "sog", "cog", "depth", "water_temp",
    "wind_speed", "wind_dir", "wind_east", "wind_north", "app_wind_speed", "app_wind_angle",
    "current_speed", "current_dir", "current_east", "current_north",
    "current_speed_paper", "current_dir_paper",
    "wheel1_speed", "wheel2_speed", "wheel3_speed", "wheel4_speed", "throttle",
)  # fmt: skip

HOST_STAMPS = {"t_mono_ns": INT, "t_wall_ns": INT}

LOCATION_FIX = {
    "title": "foxglove.LocationFix",
    "description": "A navigation satellite fix for any Global Navigation Satellite System",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
        },
        "frame_id": {"type": "string"},
        "latitude": {"type": "number"},
        "longitude": {"type": "number"},
        "altitude": {"type": "number"},
        "position_covariance": {
            "type": "array",
            "items": {"type": "number"},
            "minItems": 9,
            "maxItems": 9,
        },
        "position_covariance_type": {"type": "integer", "enum": [0, 1, 2, 3]},
    },
}

_SCHEMAS: dict[str, tuple[str, dict[str, Any]]] = {
    "/bridge/frame": (
        "forcemap.BridgeFrame",
        _obj(
            "forcemap.BridgeFrame",
            {
                "boot_id": {"type": "integer"},
                "seq": {"type": "integer"},
                "t_us": {"type": "integer"},
                "type": {"type": "string"},
                "flags": {"type": "integer"},
                "fields": {"type": "object"},
                "t_host": NUM,
                **HOST_STAMPS,
            },
            ["boot_id", "seq", "t_us", "type", "fields"],
        ),
    ),
    "/bridge/hello": (
        "forcemap.BridgeHello",
        _obj(
            "forcemap.BridgeHello",
            {
                "boot_id": {"type": "integer"},
                "fields": {"type": "object"},
                **HOST_STAMPS,
            },
            ["boot_id", "fields"],
        ),
    ),
    "/bridge/status": (
        "forcemap.BridgeStatus",
        _obj(
            "forcemap.BridgeStatus",
            {
                "boot_id": {"type": "integer"},
                "fields": {"type": "object"},
                **HOST_STAMPS,
            },
            ["boot_id", "fields"],
        ),
    ),
    "/nmea/sentence": (
        "forcemap.NmeaSentence",
        _obj(
            "forcemap.NmeaSentence",
            {
                "text": {"type": "string"},
                "valid": BOOL,
                "reason": {"type": "string"},
                "talker": {"type": "string"},
                "type": {"type": "string"},
                "source": {"type": "string"},
                **HOST_STAMPS,
            },
            ["text", "valid", "reason"],
        ),
    ),
    "/boat/state": (
        "forcemap.BoatState",
        _obj(
            "forcemap.BoatState",
            {
                "t": {"type": "number"},
                "lat": NUM,
                "lon": NUM,
                "v_east": NUM,
                "v_north": NUM,
                "sog": NUM,
                "cog": NUM,
                "heading": NUM,
                "yaw_rate": NUM,
                "throttle": NUM,
                "source": STR,
            },
            ["t"],
            description="Navigation state; angles in compass degrees, speeds in m/s",
        ),
    ),
    "/wind/apparent": (
        "forcemap.ApparentWind",
        _obj(
            "forcemap.ApparentWind",
            {
                "t": {"type": "number"},
                "speed": NUM,
                "angle": NUM,
                "rate_hz": NUM,
                "vane_raw": INT,
                "source": STR,
            },
            ["t"],
            description="Apparent wind: speed m/s, angle FROM, degrees clockwise from the bow",
        ),
    ),
    "/wind/true": (
        "forcemap.TrueWind",
        _obj(
            "forcemap.TrueWind",
            {
                "t": {"type": "number"},
                "speed": NUM,
                "dir": NUM,
                "east": NUM,
                "north": NUM,
                "app_speed": NUM,
                "app_angle": NUM,
                "heading": NUM,
                "boat_east": NUM,
                "boat_north": NUM,
                "source": STR,
            },
            ["t"],
            description="Wind over ground W = R + V_boat; dir is where it comes FROM",
        ),
    ),
    "/current": (
        "forcemap.Current",
        _obj(
            "forcemap.Current",
            {
                "t": {"type": "number"},
                "estimator": {"type": "string"},
                "speed": NUM,
                "dir": NUM,
                "east": NUM,
                "north": NUM,
                "speed_lsq": NUM,
                "dir_lsq": NUM,
                "east_lsq": NUM,
                "north_lsq": NUM,
                "speed_paper": NUM,
                "dir_paper": NUM,
                "east_paper": NUM,
                "north_paper": NUM,
                "flow_fwd": NUM,
                "flow_stbd": NUM,
                "ambiguous": {"type": ["boolean", "null"]},
                "wheels": {"type": "array", "items": NUM},
            },
            ["t", "estimator"],
            description="Water velocity over ground C = F + V_boat; dir is where it flows TO",
        ),
    ),
    "/depth": (
        "forcemap.Depth",
        _obj(
            "forcemap.Depth",
            {
                "t": {"type": "number"},
                "depth": NUM,
                "water_temp": NUM,
                "sentence": STR,
            },
            ["t"],
            description="Depth below the surface (m), water temperature (deg C)",
        ),
    ),
    "/fix": ("foxglove.LocationFix", LOCATION_FIX),
    "/timesync": (
        "forcemap.ClockMapping",
        _obj(
            "forcemap.ClockMapping",
            {
                "source": {"type": "string"},
                "epoch": {"type": "string"},
                "offset_s": {"type": "number"},
                "drift_ppm": {"type": "number"},
                "ref_device_s": {"type": "number"},
                "points": {"type": "integer"},
                "span_s": {"type": "number"},
                "kind": STR,
            },
            ["source", "epoch", "offset_s", "drift_ppm"],
            description="host_s = device_s + offset_s + drift_ppm*1e-6*(device_s - ref_device_s); "
            "kind 'utc' gives the correction added to host time to get GPS UTC",
        ),
    ),
    "/diagnostics": (
        "forcemap.Diagnostics",
        _obj(
            "forcemap.Diagnostics",
            {
                "t": {"type": "number"},
                "counters": {"type": "object"},
            },
            ["counters"],
            extra=True,
        ),
    ),
    "/samples": (
        "forcemap.Sample",
        _obj(
            "forcemap.Sample",
            {c: NUM for c in SAMPLE_COLUMNS},
            list(SAMPLE_COLUMNS),
            description="One samples-table row (docs/CONVENTIONS.md)",
        ),
    ),
}

MAVLINK_SCHEMA = (
    "forcemap.MavlinkMessage",
    _obj(
        "forcemap.MavlinkMessage",
        {
            "mavpackettype": {"type": "string"},
            "_src": {"type": "array", "items": {"type": "integer"}},
        },
        ["mavpackettype"],
        extra=True,
        description="A decoded MAVLink message, fields as pymavlink names them",
    ),
)

TOPICS: tuple[str, ...] = tuple(_SCHEMAS) + ("/mavlink/<MSGNAME>",)


def schema_for(topic: str) -> tuple[str, dict[str, Any]]:
    """(schema name, JSON schema) for a topic. Raises KeyError for an unknown topic."""
    if topic.startswith("/mavlink/"):
        return MAVLINK_SCHEMA
    return _SCHEMAS[topic]


def schema_bytes(topic: str) -> tuple[str, bytes]:
    """(schema name, schema as UTF-8 JSON bytes) for writing an MCAP schema record."""
    name, schema = schema_for(topic)
    return name, json.dumps(schema, separators=(",", ":")).encode()


def location_fix(
    t_ns: int,
    lat: float,
    lon: float,
    alt: float = 0.0,
    h_acc: float | None = None,
    v_acc: float | None = None,
    frame_id: str = "gps",
) -> dict[str, Any]:
    """A foxglove.LocationFix message. ``h_acc``/``v_acc``: 1-sigma accuracy in metres if known."""
    cov = [0.0] * 9
    ctype = 0
    if h_acc is not None:
        cov[0] = cov[4] = h_acc * h_acc
        cov[8] = (v_acc if v_acc is not None else 2 * h_acc) ** 2
        ctype = 2
    return {
        "timestamp": {"sec": t_ns // 1_000_000_000, "nsec": t_ns % 1_000_000_000},
        "frame_id": frame_id,
        "latitude": lat,
        "longitude": lon,
        "altitude": alt,
        "position_covariance": cov,
        "position_covariance_type": ctype,
    }
