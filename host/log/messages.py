"""Every logged message as one typed record: the dataclass is both the JSON encoding and the JSON schema.

    rec = Depth(t=..., depth=3.2, water_temp=None, sentence="DBT", source="nmea")
    rec.to_json()          # the message as logged (a dict of JSON values)
    Depth.json_schema()    # its MCAP ``jsonschema`` schema, from the field types
    Depth.NAME             # its schema name

How a record's fields become its schema: forcemap.host.log.record. The records of raw inputs (bridge
frames, NMEA sentences, MAVLink and DataFlash messages, raw bytes) are in
forcemap.host.log.raw_messages, the ones published live only in forcemap.host.log.live_messages;
`TOPIC_TYPES` and `record_type` here are the one table of every topic.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from forcemap.host.log.live_messages import LIVE_TOPIC_TYPES
from forcemap.host.log.plan_records import Replan
from forcemap.host.log.raw_messages import (
    BridgeFrame,
    BridgeHello,
    BridgeStatus,
    DataflashMessage,
    NmeaSentence,
    RawChunk,
    RawMessage,
    SourceReading,
)
from forcemap.host.log.record import (  # noqa: F401 - part of this API
    FoxgloveLog,
    GeoJSON,
    Grid,
    LocationFix,
    Record,
    Time,
)

Opt = float | None


# --- derived ----------------------------------------------------------------------------------------


@dataclass(slots=True)
class BoatStateRecord(Record):
    NAME = "forcemap.BoatState"
    DESCRIPTION = "Navigation state; angles in compass degrees, speeds in m/s"
    t: float
    lat: Opt = None
    lon: Opt = None
    v_east: Opt = None
    v_north: Opt = None
    sog: Opt = None
    cog: Opt = None
    heading: Opt = None
    yaw_rate: Opt = None
    throttle: Opt = None
    source: str | None = None


@dataclass(slots=True)
class ApparentWind(Record):
    NAME = "forcemap.ApparentWind"
    DESCRIPTION = "Apparent wind: speed m/s, angle FROM, degrees clockwise from the bow"
    t: float
    speed: Opt = None
    angle: Opt = None
    rate_hz: Opt = None
    vane_raw: int | None = None
    source: str | None = None


@dataclass(slots=True)
class TrueWind(Record):
    NAME = "forcemap.TrueWind"
    DESCRIPTION = (
        "Wind: dir is where it comes FROM. route 'computed': over ground, W = R + V_boat; "
        "'instrument': the instrument's own true wind (MWV T, MWD, MAVLink WIND)"
    )
    t: float
    speed: Opt = None
    dir: Opt = None
    east: Opt = None
    north: Opt = None
    app_speed: Opt = None
    app_angle: Opt = None
    heading: Opt = None
    boat_east: Opt = None
    boat_north: Opt = None
    source: str | None = None
    route: str = "computed"
    sentence: str | None = None


@dataclass(slots=True)
class Current(Record):
    NAME = "forcemap.Current"
    DESCRIPTION = "Water velocity over ground C = F + V_boat from the paddle wheels; dir is TO"
    t: float
    estimator: str
    speed: Opt = None
    dir: Opt = None
    east: Opt = None
    north: Opt = None
    speed_lsq: Opt = None
    dir_lsq: Opt = None
    east_lsq: Opt = None
    north_lsq: Opt = None
    speed_paper: Opt = None
    dir_paper: Opt = None
    east_paper: Opt = None
    north_paper: Opt = None
    flow_fwd: Opt = None
    flow_stbd: Opt = None
    ambiguous: bool | None = None
    wheels: list[Opt] = field(default_factory=list)


@dataclass(slots=True)
class SetAndDrift(Record):
    NAME = "forcemap.SetAndDrift"
    DESCRIPTION = (
        "Current from speed through water: ground velocity - STW along the heading "
        "(docs/COMPENSATION.md); dir is where the water flows TO"
    )
    t: float
    speed: float
    dir: float
    east: float
    north: float
    stw: float
    heading: float
    boat_east: float
    boat_north: float
    source: str | None = None


@dataclass(slots=True)
class Depth(Record):
    NAME = "forcemap.Depth"
    DESCRIPTION = "Depth below the surface (m), water temperature (deg C)"
    t: float
    depth: Opt = None
    water_temp: Opt = None
    sentence: str | None = None
    source: str | None = None


@dataclass(slots=True)
class WaterSpeed(Record):
    NAME = "forcemap.WaterSpeed"
    DESCRIPTION = "Speed through water along the heading (m/s), as the log reports it"
    t: float
    stw: float
    sentence: str | None = None
    source: str | None = None


@dataclass(slots=True)
class ClockMapping(Record):
    NAME = "forcemap.ClockMapping"
    DESCRIPTION = (
        "host_s = device_s + offset_s + drift_ppm*1e-6*(device_s - ref_device_s); "
        "kind 'utc' gives the correction added to host time to get GPS UTC"
    )
    source: str
    epoch: str
    offset_s: float
    drift_ppm: float
    ref_device_s: float = 0.0
    points: int = 0
    span_s: float = 0.0
    kind: str | None = None


@dataclass(slots=True)
class Diagnostics(Record):
    NAME = "forcemap.Diagnostics"
    t: float
    counters: dict[str, Any]
    event: dict[str, Any] | None = None


@dataclass(slots=True)
class DaemonEvent(Record):
    NAME = "forcemap.DaemonEvent"
    EXTRA = True
    event: str
    details: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"event": self.event, **self.details}

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        return {
            "title": cls.NAME,
            "type": "object",
            "properties": {"event": {"type": "string"}},
            "required": ["event"],
        }


@dataclass(slots=True)
class DaemonStatus(Record):
    NAME = "forcemap.DaemonStatus"
    DESCRIPTION = "The daemon's status snapshot (the same as its status line)"
    EXTRA = True
    snapshot: dict[str, Any]

    def to_json(self) -> dict[str, Any]:
        return self.snapshot

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        return {"title": cls.NAME, "type": "object", "description": cls.DESCRIPTION}


@dataclass(slots=True)
class Sample(Record):
    """One samples-table row (docs/CONVENTIONS.md); an empty column is null."""

    NAME = "forcemap.Sample"
    DESCRIPTION = "One samples-table row (docs/CONVENTIONS.md)"
    t: float
    lat: Opt = None
    lon: Opt = None
    heading: Opt = None
    yaw_rate: Opt = None
    sog: Opt = None
    cog: Opt = None
    depth: Opt = None
    water_temp: Opt = None
    wind_speed: Opt = None
    wind_dir: Opt = None
    wind_east: Opt = None
    wind_north: Opt = None
    app_wind_speed: Opt = None
    app_wind_angle: Opt = None
    current_speed: Opt = None
    current_dir: Opt = None
    current_east: Opt = None
    current_north: Opt = None
    current_speed_paper: Opt = None
    current_dir_paper: Opt = None
    wheel1_speed: Opt = None
    wheel2_speed: Opt = None
    wheel3_speed: Opt = None
    wheel4_speed: Opt = None
    throttle: Opt = None
    stw: Opt = None
    current_speed_stw: Opt = None
    current_dir_stw: Opt = None
    wind_speed_instrument: Opt = None
    wind_dir_instrument: Opt = None
    roll: Opt = None
    pitch: Opt = None
    depth_raw: Opt = None
    bottom_lost: Opt = None


SAMPLE_COLUMNS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(Sample))


# the record type logged on each fixed topic (``/mavlink/<MSG>`` and ``/dataflash/<MSG>`` are raw)
TOPIC_TYPES: dict[str, type[Record]] = {
    "/bridge/frame": BridgeFrame,
    "/bridge/hello": BridgeHello,
    "/bridge/status": BridgeStatus,
    "/nmea/sentence": NmeaSentence,
    "/source/reading": SourceReading,
    "/boat/state": BoatStateRecord,
    "/wind/apparent": ApparentWind,
    "/wind/true": TrueWind,
    "/current": Current,
    "/current/stw": SetAndDrift,
    "/water/speed": WaterSpeed,
    "/depth": Depth,
    "/fix": LocationFix,
    "/timesync": ClockMapping,
    "/diagnostics": Diagnostics,
    "/samples": Sample,
    "/daemon/event": DaemonEvent,
    "/daemon/status": DaemonStatus,
    "/plan/replan": Replan,
}


def record_type(topic: str) -> type[Record] | None:
    """The record type logged on ``topic``, or None for a topic no record describes."""
    if topic.startswith("/mavlink/"):
        return RawMessage
    if topic.startswith("/dataflash/"):
        return DataflashMessage
    if topic.startswith("/raw/"):
        return RawChunk
    if topic.startswith("/map/layers/"):
        return GeoJSON
    if topic.startswith("/map/") and topic not in LIVE_TOPIC_TYPES:
        return Grid
    return TOPIC_TYPES.get(topic) or LIVE_TOPIC_TYPES.get(topic)


def as_json(message: Record | dict[str, Any]) -> dict[str, Any]:
    """A record's JSON dict; a dict passes through."""
    return message.to_json() if isinstance(message, Record) else message
