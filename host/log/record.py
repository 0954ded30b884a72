"""The base of every logged message: a dataclass whose fields give both its JSON and its JSON schema.

A field's type gives its schema: ``float`` is a number, ``int`` an integer, ``X | None`` may be
null, ``list[X]`` an array, ``dict[str, Any]`` an object, a nested record its own schema. Fields
without a default are required. Foxglove's types (``foxglove.LocationFix``) follow Foxglove's
published schemas, so Foxglove draws them. The message types are in forcemap.host.log.messages.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import dataclass
from typing import Any, ClassVar


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


LOG_LEVELS = ("UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL")


@dataclass(slots=True)
class FoxgloveLog(Record):
    """foxglove.Log, as Foxglove publishes it (its Log panel lists it)."""

    NAME = "foxglove.Log"
    DESCRIPTION = "A log message"
    timestamp: Time
    level: int
    message: str
    name: str
    file: str = ""
    line: int = 0

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        if cls._schema is None:
            s = _object_schema(cls)
            del s["required"], s["additionalProperties"]
            s["properties"]["level"] = {
                "title": "foxglove.LogLevel",
                "oneOf": [{"title": n, "const": i} for i, n in enumerate(LOG_LEVELS)],
            }
            cls._schema = s
        return cls._schema

    @classmethod
    def at(cls, t_ns: int, level: str, message: str, name: str) -> FoxgloveLog:
        ts = Time(t_ns // 1_000_000_000, t_ns % 1_000_000_000)
        return cls(ts, LOG_LEVELS.index(level), message, name)


@dataclass(slots=True)
class GeoJSON(Record):
    """foxglove.GeoJSON: a GeoJSON document as a string (its Map panel draws it)."""

    NAME = "foxglove.GeoJSON"
    DESCRIPTION = "GeoJSON data for annotating maps"
    geojson: str

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        return {
            "title": cls.NAME,
            "description": cls.DESCRIPTION,
            "type": "object",
            "properties": {"geojson": {"type": "string"}},
        }


FLOAT32 = 7  # foxglove.NumericType


@dataclass(slots=True)
class Grid(Record):
    """foxglove.Grid: a 2-D grid of float32 fields, row-major from its origin (the 3D panel draws it)."""

    NAME = "foxglove.Grid"
    DESCRIPTION = "A 2D grid of data"
    timestamp: Time
    frame_id: str
    pose: dict[str, Any]
    column_count: int
    cell_size: dict[str, Any]
    row_stride: int
    cell_stride: int
    fields: list[dict[str, Any]]
    data: str  # base64

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        vec = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
        quat = {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}
        return {
            "title": cls.NAME,
            "description": cls.DESCRIPTION,
            "type": "object",
            "properties": {
                "timestamp": Time.json_schema(),
                "frame_id": {"type": "string"},
                "pose": {
                    "type": "object",
                    "properties": {"position": vec, "orientation": quat},
                },
                "column_count": {"type": "integer", "minimum": 0},
                "cell_size": {
                    "type": "object",
                    "properties": {"x": {"type": "number"}, "y": {"type": "number"}},
                },
                "row_stride": {"type": "integer", "minimum": 0},
                "cell_stride": {"type": "integer", "minimum": 0},
                "fields": {
                    "type": "array",
                    "items": {
                        "type": "object",
                        "properties": {
                            "name": {"type": "string"},
                            "offset": {"type": "integer", "minimum": 0},
                            "type": {"type": "integer"},
                        },
                    },
                },
                "data": {"type": "string", "contentEncoding": "base64"},
            },
        }
