"""The records of raw inputs as logged: bridge frames, NMEA sentences, source readings, MAVLink and
DataFlash messages, and raw bytes (`/raw/<port>`). Their topics are in forcemap.host.log.messages.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from forcemap.host.log.record import Record


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
class SourceReading(Record):
    """One reading of a quantity (position, heading, ...) from one source, used or not."""

    NAME = "forcemap.SourceReading"
    quantity: str
    source: str
    value: list[float | None]
    used: bool


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
