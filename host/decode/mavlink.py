"""MAVLink: bulk decoding with pymavlink's ``parse_buffer``, bad packets counted, SI dicts out."""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

# messages the pipeline turns into SI values; everything else is only logged raw
USED = (
    "GLOBAL_POSITION_INT",
    "GPS_RAW_INT",
    "ATTITUDE",
    "VFR_HUD",
    "SYSTEM_TIME",
    "HEARTBEAT",
    "WIND",
    "RANGEFINDER",
    "DISTANCE_SENSOR",
    "WATER_DEPTH",
)
SENSOR_DOWNWARD = 25  # MAV_SENSOR_ROTATION_PITCH_270: a distance sensor looking down (echo sounder)
MAV_AUTOPILOT_INVALID = 8
MAV_TYPE_GCS = 6


class MavlinkDecoder:
    """Bytes in any chunking to messages. Bad CRCs and junk are counted, never raised.

    ``bad_crc`` counts packets with a bad CRC by ``(sysid, compid, msgid)``; ``junk_bytes`` counts
    bytes that were not part of any packet; ``messages`` counts good ones by type.
    """

    def __init__(self) -> None:
        self._mav = mavlink.MAVLink(None)
        self._mav.robust_parsing = True
        self.messages: Counter[str] = Counter()
        self.bad_crc: Counter[tuple[int, int, int]] = Counter()
        self.bad_reasons: Counter[str] = Counter()
        self.junk_bytes = 0
        self.bytes_in = 0
        self.errors = 0

    def reset(self) -> None:
        """Drop a partial packet (the port was reopened); the counters stay."""
        self._mav = mavlink.MAVLink(None)
        self._mav.robust_parsing = True

    def feed(self, data: bytes) -> list[Any]:
        """Add bytes; return the good messages they completed (BAD_DATA is counted, not returned)."""
        self.bytes_in += len(data)
        try:
            msgs = self._mav.parse_buffer(data)
        except Exception:  # pymavlink can still raise on exotic garbage; restart the parser
            self.errors += 1
            self.bad_reasons["exception"] += 1
            self.reset()
            return []
        if not msgs:
            return []
        out = []
        for m in msgs:
            t = m.get_type()
            if t == "BAD_DATA":
                self._bad(m)
            else:
                self.messages[t] += 1
                out.append(m)
        return out

    def _bad(self, m: Any) -> None:
        reason = str(getattr(m, "reason", ""))
        raw = bytes(getattr(m, "data", b""))
        if "CRC" in reason and len(raw) >= 6:
            if raw[0] == 0xFD and len(raw) >= 10:
                key = (raw[5], raw[6], raw[7] | raw[8] << 8 | raw[9] << 16)
            else:
                key = (raw[3], raw[4], raw[5])
            self.bad_crc[key] += 1
            self.bad_reasons["crc"] += 1
        elif "prefix" in reason.lower():
            self.junk_bytes += len(raw)
            self.bad_reasons["junk"] += 1
        elif "unknown MAVLink message ID" in reason or "unknown" in reason.lower():
            self.bad_reasons["unknown_msgid"] += 1
        else:
            self.bad_reasons["other"] += 1

    def counters(self) -> dict[str, Any]:
        return {
            "bytes": self.bytes_in,
            "messages": sum(self.messages.values()),
            "bad_crc": sum(self.bad_crc.values()),
            "bad_crc_by_sender_msgid": {f"{s}/{c}/{i}": n for (s, c, i), n in self.bad_crc.items()},
            "bad_by_reason": dict(self.bad_reasons),
            "junk_bytes": self.junk_bytes,
        }


def _u16(v: int, scale: float, missing: int = 65535) -> float | None:
    return None if v == missing else v * scale


def to_si(m: Any) -> dict[str, Any] | None:
    """SI values of a message the pipeline uses, or None. Angles in degrees, speeds in m/s."""
    t = m.get_type()
    if t == "GLOBAL_POSITION_INT":
        return {
            "time_boot_ms": m.time_boot_ms,
            "lat": m.lat * 1e-7,
            "lon": m.lon * 1e-7,
            "alt": m.alt * 1e-3,
            "relative_alt": m.relative_alt * 1e-3,
            "v_north": m.vx * 0.01,
            "v_east": m.vy * 0.01,
            "v_down": m.vz * 0.01,
            "heading": _u16(m.hdg, 0.01),
        }
    if t == "GPS_RAW_INT":
        return {
            "time_usec": m.time_usec,
            "fix_type": m.fix_type,
            "lat": m.lat * 1e-7,
            "lon": m.lon * 1e-7,
            "alt": m.alt * 1e-3,
            "eph": _u16(m.eph, 0.01),
            "epv": _u16(m.epv, 0.01),
            "sog": _u16(m.vel, 0.01),
            "cog": _u16(m.cog, 0.01),
            "satellites": None if m.satellites_visible == 255 else m.satellites_visible,
        }
    if t == "ATTITUDE":
        return {
            "time_boot_ms": m.time_boot_ms,
            "roll": m.roll,
            "pitch": m.pitch,
            "roll_deg": math.degrees(m.roll),
            "pitch_deg": math.degrees(m.pitch),
            "yaw": m.yaw,
            "heading": math.degrees(m.yaw) % 360.0,
            "yaw_rate": math.degrees(m.yawspeed),
        }
    if t == "VFR_HUD":
        return {
            "groundspeed": m.groundspeed,
            "airspeed": m.airspeed,
            "heading": float(m.heading),
            "throttle": float(m.throttle),
            "alt": m.alt,
            "climb": m.climb,
        }
    if t == "WIND":  # ArduPilot: direction the wind comes FROM, deg; speed m/s
        return {"dir": m.direction % 360.0, "speed": m.speed}
    if t == "RANGEFINDER":
        return {"distance": m.distance}
    if t == "DISTANCE_SENSOR":
        return {
            "time_boot_ms": m.time_boot_ms,
            "distance": m.current_distance * 0.01,
            "orientation": m.orientation,
            "valid": m.min_distance <= m.current_distance <= m.max_distance,
        }
    if t == "WATER_DEPTH":
        return {
            "time_boot_ms": m.time_boot_ms,
            "distance": m.distance,
            "temperature": m.temperature,
            "healthy": bool(m.healthy),
        }
    if t == "SYSTEM_TIME":
        return {"time_unix_usec": m.time_unix_usec, "time_boot_ms": m.time_boot_ms}
    if t == "HEARTBEAT":
        return {
            "type": m.type,
            "autopilot": m.autopilot,
            "base_mode": m.base_mode,
            "custom_mode": m.custom_mode,
            "system_status": m.system_status,
        }
    return None


_FIX_FIELDS: dict[str, tuple[str, ...]] = {}


def raw_dict(m: Any) -> dict[str, Any]:
    """The message's fields as JSON-able values (NaN as None, text as str, other bytes as hex), with its
    sender. What pymavlink's ``to_dict`` gives, built without its per-field method calls (hot path)."""
    d: dict[str, Any] = {"mavpackettype": m._type}
    for a in m._fieldnames:
        d[a] = getattr(m, a)
    fix = _FIX_FIELDS.get(m._type)
    if fix is None:
        fix = _FIX_FIELDS[m._type] = tuple(
            k for k, v in d.items() if isinstance(v, float | bytes | bytearray | list)
        )
    for k in fix:
        v = d[k]
        if isinstance(v, float):
            if not math.isfinite(v):
                d[k] = None
        elif isinstance(v, bytes):  # a char[] field: text, as pymavlink's to_dict gives it
            d[k] = v.decode(errors="backslashreplace").rstrip("\x00")
        elif isinstance(v, bytearray):
            d[k] = bytes(v).hex()
        elif isinstance(v, list):
            d[k] = [None if isinstance(x, float) and not math.isfinite(x) else x for x in v]
    d["_src"] = [m.get_srcSystem(), m.get_srcComponent()]
    return d


def is_vehicle(m: Any, vehicle: tuple[int, int] | None) -> bool:
    """Whether ``m`` comes from the vehicle's autopilot (the first non-GCS autopilot heartbeat)."""
    if vehicle is None:
        return m.get_srcComponent() == 1
    return (m.get_srcSystem(), m.get_srcComponent()) == vehicle


def vehicle_of(m: Any) -> tuple[int, int] | None:
    """The (sysid, compid) a HEARTBEAT identifies as a vehicle autopilot, else None."""
    if m.get_type() != "HEARTBEAT":
        return None
    if m.autopilot == MAV_AUTOPILOT_INVALID or m.type == MAV_TYPE_GCS:
        return None
    return (m.get_srcSystem(), m.get_srcComponent())
