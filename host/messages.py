"""Every logged message as one typed record: the dataclass is both the JSON encoding and the JSON schema.

    rec = Depth(t=..., depth=3.2, water_temp=None, sentence="DBT", source="nmea")
    rec.to_json()          # the message as logged (a dict of JSON values)
    Depth.json_schema()    # its MCAP ``jsonschema`` schema, from the field types
    Depth.NAME             # its schema name

A field's type gives its schema: ``float`` is a number, ``int`` an integer, ``X | None`` may be
null, ``list[X]`` an array, ``dict[str, Any]`` an object, a nested record its own schema. Fields
without a default are required. Foxglove's types (``foxglove.LocationFix``) follow Foxglove's
published schemas, so Foxglove draws them.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass, field
from typing import Any, ClassVar

Opt = float | None


class Record:
    """Base of the logged message types. Subclasses are dataclasses with a ``NAME``."""

    NAME: ClassVar[str] = ""
    DESCRIPTION: ClassVar[str] = ""
    EXTRA: ClassVar[bool] = False  # further properties allowed (free-form messages)
    _names: ClassVar[tuple[str, ...]] = ()
    _schema: ClassVar[dict[str, Any] | None] = None

    def __init_subclass__(cls, **kw: Any) -> None:
        super().__init_subclass__(**kw)
        cls._names = ()
        cls._schema = None

    def to_json(self) -> dict[str, Any]:
        """The message as a dict of JSON values (nested records as dicts)."""
        names = type(self)._names or _field_names(type(self))
        out = {}
        for n in names:
            v = getattr(self, n)
            out[n] = v.to_json() if isinstance(v, Record) else v
        return out

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        """The JSON schema of this record type (built once from its fields)."""
        if cls._schema is None:
            cls._schema = _object_schema(cls)
        return cls._schema


def _field_names(cls: type[Record]) -> tuple[str, ...]:
    cls._names = tuple(f.name for f in dataclasses.fields(cls))  # type: ignore[arg-type]
    return cls._names


def _type_schema(tp: Any) -> dict[str, Any]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        inner = _type_schema(args[0]) if len(args) == 1 else {}
        if "type" in inner and isinstance(inner["type"], str):
            return {**inner, "type": [inner["type"], "null"]}
        return {"anyOf": [inner, {"type": "null"}]}
    if origin is list:
        (item,) = typing.get_args(tp) or (Any,)
        return {"type": "array", "items": _type_schema(item)}
    if origin is dict or tp is dict:
        return {"type": "object"}
    if isinstance(tp, type) and issubclass(tp, Record):
        return tp.json_schema()
    simple = {float: "number", int: "integer", str: "string", bool: "boolean"}
    return {"type": simple[tp]} if tp in simple else {}


def _object_schema(cls: type[Record]) -> dict[str, Any]:
    hints = typing.get_type_hints(cls)
    props: dict[str, Any] = {}
    required = []
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        props[f.name] = _type_schema(hints[f.name])
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            required.append(f.name)
    schema: dict[str, Any] = {"title": cls.NAME, "type": "object"}
    if cls.DESCRIPTION:
        schema["description"] = cls.DESCRIPTION
    schema["properties"] = props
    if required:
        schema["required"] = required
    if not cls.EXTRA:
        schema["additionalProperties"] = False
    return schema


# --- Foxglove ---------------------------------------------------------------------------------------


@dataclass(slots=True)
class Time(Record):
    """Foxglove's ``time``: seconds and nanoseconds since the UNIX epoch."""

    NAME = "time"
    sec: int
    nsec: int

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        return {
            "type": "object",
            "title": "time",
            "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
            },
        }


COVARIANCE_TYPES = ("UNKNOWN", "APPROXIMATED", "DIAGONAL_KNOWN", "KNOWN")


@dataclass(slots=True)
class LocationFix(Record):
    """foxglove.LocationFix, as Foxglove publishes it (its Map panel draws it)."""

    NAME = "foxglove.LocationFix"
    DESCRIPTION = "A navigation satellite fix for any Global Navigation Satellite System"
    timestamp: Time
    frame_id: str
    latitude: float
    longitude: float
    altitude: float
    position_covariance: list[float]
    position_covariance_type: int

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        if cls._schema is None:
            s = _object_schema(cls)
            del s["required"], s["additionalProperties"]  # Foxglove's schema has neither
            s["properties"]["position_covariance"] |= {"minItems": 9, "maxItems": 9}
            s["properties"]["position_covariance_type"] = {
                "title": "foxglove.PositionCovarianceType",
                "oneOf": [{"title": n, "const": i} for i, n in enumerate(COVARIANCE_TYPES)],
            }
            cls._schema = s
        return cls._schema

    @classmethod
    def at(
        cls,
        t_ns: int,
        lat: float,
        lon: float,
        alt: float = 0.0,
        h_acc: float | None = None,
        v_acc: float | None = None,
        frame_id: str = "gps",
    ) -> LocationFix:
        """A fix at UNIX ``t_ns``; ``h_acc``/``v_acc``: 1-sigma accuracy in metres if known."""
        cov = [0.0] * 9
        ctype = 0
        if h_acc is not None:
            cov[0] = cov[4] = h_acc * h_acc
            cov[8] = (v_acc if v_acc is not None else 2 * h_acc) ** 2
            ctype = 2
        ts = Time(t_ns // 1_000_000_000, t_ns % 1_000_000_000)
        return cls(ts, frame_id, lat, lon, alt, cov, ctype)


# --- raw inputs -------------------------------------------------------------------------------------


@dataclass(slots=True)
class BridgeFrame(Record):
    NAME = "forcemap.BridgeFrame"
    boot_id: int
    seq: int
    t_us: int
    type: str
    flags: int
    fields: dict[str, Any]
    t_host: float | None = None
    t_mono_ns: int | None = None
    t_wall_ns: int | None = None


@dataclass(slots=True)
class BridgeHello(Record):
    NAME = "forcemap.BridgeHello"
    boot_id: int
    fields: dict[str, Any]
    t_mono_ns: int | None = None
    t_wall_ns: int | None = None


@dataclass(slots=True)
class BridgeStatus(Record):
    NAME = "forcemap.BridgeStatus"
    boot_id: int
    fields: dict[str, Any]
    t_mono_ns: int | None = None
    t_wall_ns: int | None = None


@dataclass(slots=True)
class NmeaSentence(Record):
    NAME = "forcemap.NmeaSentence"
    text: str
    valid: bool
    reason: str
    talker: str
    type: str
    source: str | None = None
    t_mono_ns: int | None = None
    t_wall_ns: int | None = None


@dataclass(slots=True)
class RawMessage(Record):
    """A decoded MAVLink or DataFlash message, fields as pymavlink names them (flat)."""

    NAME = "forcemap.MavlinkMessage"
    DESCRIPTION = "A decoded MAVLink message, fields as pymavlink names them"
    EXTRA = True
    fields: dict[str, Any]

    def to_json(self) -> dict[str, Any]:
        return self.fields

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        return {
            "title": cls.NAME,
            "type": "object",
            "description": cls.DESCRIPTION,
            "properties": {
                "mavpackettype": {"type": "string"},
                "_src": {"type": "array", "items": {"type": "integer"}},
            },
            "required": ["mavpackettype"],
        }


@dataclass(slots=True)
class DataflashMessage(RawMessage):
    NAME = "forcemap.DataflashMessage"
    DESCRIPTION = "A DataFlash log record, fields in the log's own units (see its FMTU/MULT)"


@dataclass(slots=True)
class RawChunk(Record):
    NAME = "forcemap.RawChunk"
    DESCRIPTION = "Bytes as read from a port (base64) with their arrival stamps"
    t_mono_ns: int
    t_wall_ns: int
    data: str


# --- derived ----------------------------------------------------------------------------------------


@dataclass(slots=True)
class BoatState(Record):
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


SAMPLE_COLUMNS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(Sample))

# the record type logged on each fixed topic (``/mavlink/<MSG>`` and ``/dataflash/<MSG>`` are raw)
TOPIC_TYPES: dict[str, type[Record]] = {
    "/bridge/frame": BridgeFrame,
    "/bridge/hello": BridgeHello,
    "/bridge/status": BridgeStatus,
    "/nmea/sentence": NmeaSentence,
    "/boat/state": BoatState,
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
}


def record_type(topic: str) -> type[Record] | None:
    """The record type logged on ``topic``, or None for a topic no record describes."""
    if topic.startswith("/mavlink/"):
        return RawMessage
    if topic.startswith("/dataflash/"):
        return DataflashMessage
    if topic.startswith("/raw/"):
        return RawChunk
    return TOPIC_TYPES.get(topic)


def as_json(message: Record | dict[str, Any]) -> dict[str, Any]:
    """A record's JSON dict; a dict passes through."""
    return message.to_json() if isinstance(message, Record) else message
