"""NMEA 0183: split lines from any chunking, check them strictly, extract SI values. Never raises."""

from __future__ import annotations

import datetime as _dt
import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import pynmea2
from forcemap.host.compensation import depth_below_surface as depth_below_surface_m
from forcemap.host.compensation import wrap180

KNOT = 1852.0 / 3600.0
KMH = 1000.0 / 3600.0
FOOT = 0.3048
FATHOM = 1.8288
MAX_LINE = 120  # NMEA allows 82 characters; real talkers overrun a little

# Field specs per sentence type, after the address field. Each entry: "f" number, "i" integer,
# "t" hhmmss(.ss), "d" ddmmyy, "lat" ddmm.mm, "lon" dddmm.mm, "=XY" one of those letters
# (case-insensitive), "s" any text. Every field may be empty. (min_fields, max_fields, specs)
SPECS: dict[str, tuple[int, int, tuple[str, ...]]] = {
    "DPT": (2, 3, ("f", "f", "f")),
    "DBT": (6, 6, ("f", "=F", "f", "=M", "f", "=F")),
    "DBS": (6, 6, ("f", "=F", "f", "=M", "f", "=F")),
    "MTW": (2, 2, ("f", "=C")),
    "RMC": (
        11,
        13,
        ("t", "=AV", "lat", "=NS", "lon", "=EW", "f", "f", "d", "f", "=EW", "=ADENSMFRP", "=SCUV"),
    ),
    "GGA": (
        14,
        14,
        ("t", "lat", "=NS", "lon", "=EW", "i", "i", "f", "f", "=M", "f", "=M", "f", "s"),
    ),
    "VTG": (8, 9, ("f", "=T", "f", "=M", "f", "=N", "f", "=K", "=ADENSMFRP")),
    "HDT": (2, 2, ("f", "=T")),
    "HDM": (2, 2, ("f", "=M")),
    "HDG": (5, 5, ("f", "f", "=EW", "f", "=EW")),
    "VHW": (8, 8, ("f", "=T", "f", "=M", "f", "=N", "f", "=K")),
    "MWV": (5, 5, ("f", "=RT", "f", "=KMNS", "=AV")),
    "VWR": (8, 8, ("f", "=LR", "f", "=N", "f", "=M", "f", "=K")),
    "MWD": (8, 8, ("f", "=T", "f", "=M", "f", "=N", "f", "=M")),
    "ZDA": (6, 6, ("t", "i", "i", "i", "i", "i")),
    "GLL": (6, 7, ("lat", "=NS", "lon", "=EW", "t", "=AV", "=ADENSMFRP")),
}


def _xor(body: str) -> int:
    """XOR of all bytes, folded in halves on one big integer (much faster than a byte loop)."""
    b = body.encode("ascii")
    x = int.from_bytes(b, "little")
    w = 8 << max(len(b) - 1, 0).bit_length()
    while w > 8:
        w >>= 1
        x = (x >> w) ^ (x & ((1 << w) - 1))
    return x


def _is_num(s: str) -> bool:
    try:
        return math.isfinite(float(s))
    except ValueError:
        return False


def _check(kind: str, s: str) -> bool:
    if not s:
        return True
    if kind == "f":
        return _is_num(s) and "_" not in s
    if kind == "i":
        return s.lstrip("+-").isdigit()
    if kind == "t":
        hh, mm, ss = s[:2], s[2:4], s[4:]
        return (
            len(s) >= 6
            and hh.isdigit()
            and mm.isdigit()
            and _is_num(ss)
            and int(hh) < 24
            and int(mm) < 60
            and 0 <= float(ss) < 61
        )
    if kind == "d":
        return len(s) == 6 and s.isdigit() and 1 <= int(s[:2]) <= 31 and 1 <= int(s[2:4]) <= 12
    if kind in ("lat", "lon"):
        n = 2 if kind == "lat" else 3
        if not _is_num(s) or "." not in s or s.index(".") != n + 2:
            return False
        return int(s[:n]) <= (90 if kind == "lat" else 180) and float(s[n:]) < 60
    if kind[0] == "=":
        return len(s) == 1 and s.upper() in kind[1:]
    return True


def _f(s: str) -> float | None:
    return float(s) if s else None


def _latlon(v: str, hemi: str, deg_digits: int) -> float | None:
    if not v or not hemi:
        return None
    x = int(v[:deg_digits]) + float(v[deg_digits:]) / 60.0
    return -x if hemi.upper() in "SW" else x


def _tod(s: str) -> float | None:
    """Seconds since midnight UTC from hhmmss(.ss)."""
    if not s:
        return None
    return int(s[:2]) * 3600 + int(s[2:4]) * 60 + float(s[4:])


def _signed(v: str, hemi: str) -> float | None:
    if not v:
        return None
    x = float(v)
    return -x if hemi.upper() == "W" else x


def _speed(v: str, unit: str) -> float | None:
    if not v:
        return None
    return float(v) * {"N": KNOT, "K": KMH, "M": 1.0, "S": 1609.344 / 3600.0}.get(
        unit.upper(), math.nan
    )


def _utc(day: int, mon: int, year: int, tod: float | None) -> float | None:
    try:
        return _dt.datetime(year, mon, day, tzinfo=_dt.UTC).timestamp() + (tod or 0.0)
    except ValueError:
        return None


def _dpt(d: list[str]) -> dict[str, Any]:
    return {"depth_m": _f(d[0]), "offset_m": _f(d[1])}


def _dbt(d: list[str]) -> dict[str, Any]:
    m = _f(d[2])
    if m is None and d[0]:
        m = float(d[0]) * FOOT
    if m is None and d[4]:
        m = float(d[4]) * FATHOM
    return {"depth_m": m}


def _mtw(d: list[str]) -> dict[str, Any]:
    return {"water_temp": _f(d[0])}


def _rmc(d: list[str]) -> dict[str, Any]:
    tod = _tod(d[0])
    utc = None
    if d[0] and d[8]:
        yy = int(d[8][4:])
        utc = _utc(int(d[8][:2]), int(d[8][2:4]), 2000 + yy if yy < 80 else 1900 + yy, tod)
    return {
        "tod": tod,
        "status": d[1].upper() or None,
        "lat": _latlon(d[2], d[3], 2),
        "lon": _latlon(d[4], d[5], 3),
        "sog": _speed(d[6], "N"),
        "cog": _f(d[7]),
        "variation": _signed(d[9], d[10]),
        "utc": utc,
    }


def _gga(d: list[str]) -> dict[str, Any]:
    return {
        "tod": _tod(d[0]),
        "lat": _latlon(d[1], d[2], 2),
        "lon": _latlon(d[3], d[4], 3),
        "quality": int(d[5]) if d[5] else None,
        "satellites": int(d[6]) if d[6] else None,
        "hdop": _f(d[7]),
        "alt": _f(d[8]),
    }


def _gll(d: list[str]) -> dict[str, Any]:
    return {
        "lat": _latlon(d[0], d[1], 2),
        "lon": _latlon(d[2], d[3], 3),
        "tod": _tod(d[4]),
        "status": d[5].upper() or None,
    }


def _first_speed(*pairs: tuple[str, str]) -> float | None:
    """The first non-empty of (value, unit) pairs, in m/s."""
    for v, unit in pairs:
        if v:
            return _speed(v, unit)
    return None


def _vtg(d: list[str]) -> dict[str, Any]:
    return {"cog": _f(d[0]), "cog_mag": _f(d[2]), "sog": _first_speed((d[4], "N"), (d[6], "K"))}


def _hdt(d: list[str]) -> dict[str, Any]:
    return {"heading": _f(d[0])}


def _hdm(d: list[str]) -> dict[str, Any]:
    return {"heading_mag": _f(d[0])}


def _hdg(d: list[str]) -> dict[str, Any]:
    return {
        "heading_mag": _f(d[0]),
        "deviation": _signed(d[1], d[2]),
        "variation": _signed(d[3], d[4]),
    }


def _vhw(d: list[str]) -> dict[str, Any]:
    stw = _first_speed((d[4], "N"), (d[6], "K"))
    return {"heading": _f(d[0]), "heading_mag": _f(d[2]), "stw": stw}


def _mwv(d: list[str]) -> dict[str, Any]:
    a = _f(d[0])
    return {
        "angle": None if a is None else wrap180(a),
        "reference": d[1].upper() or None,
        "speed": _speed(d[2], d[3]) if d[3] else None,
        "status": d[4].upper() or None,
    }


def _vwr(d: list[str]) -> dict[str, Any]:
    a = _f(d[0])
    if a is not None and d[1].upper() == "L":
        a = -a
    # knots first: one decimal of a knot is the finest of the three
    sp = _first_speed((d[2], "N"), (d[4], "M"), (d[6], "K"))
    return {"angle": None if a is None else wrap180(a), "speed": sp}


def _mwd(d: list[str]) -> dict[str, Any]:
    sp = _first_speed((d[4], "N"), (d[6], "M"))
    return {"dir": _f(d[0]), "dir_mag": _f(d[2]), "speed": sp}


def _zda(d: list[str]) -> dict[str, Any]:
    tod = _tod(d[0])
    utc = None
    if d[0] and d[1] and d[2] and d[3]:
        utc = _utc(int(d[1]), int(d[2]), int(d[3]), tod)
    return {"tod": tod, "utc": utc}


EXTRACTORS = {
    "DPT": _dpt,
    "DBT": _dbt,
    "DBS": _dbt,
    "MTW": _mtw,
    "RMC": _rmc,
    "GGA": _gga,
    "GLL": _gll,
    "VTG": _vtg,
    "HDT": _hdt,
    "HDM": _hdm,
    "HDG": _hdg,
    "VHW": _vhw,
    "MWV": _mwv,
    "VWR": _vwr,
    "MWD": _mwd,
    "ZDA": _zda,
}


def extract(stype: str, d: list[str]) -> dict[str, Any]:
    """SI values from a validated sentence's fields (see SPECS). Missing fields are None."""
    fn = EXTRACTORS.get(stype)
    if fn is None:
        return {}
    return fn(d + [""] * (SPECS[stype][1] - len(d)))


@dataclass(slots=True)
class Sentence:
    """One line and what became of it. ``data`` holds SI values for the types in SPECS."""

    text: str
    valid: bool
    reason: str = ""
    talker: str = ""
    type: str = ""
    data: dict[str, Any] = field(default_factory=dict)

    def as_message(self) -> dict[str, Any]:
        return {
            "text": self.text,
            "valid": self.valid,
            "reason": self.reason,
            "talker": self.talker,
            "type": self.type,
        }


class LineSplitter:
    """Bytes in any chunking to complete lines (without CR/LF).

    A line longer than ``max_line`` comes out truncated once, and the rest of it up to the next
    newline is dropped, so garbage without newlines costs bounded memory.
    """

    def __init__(self, max_line: int = 4 * MAX_LINE):
        self._buf = bytearray()
        self._discard = False
        self.max_line = max_line

    def feed(self, data: bytes) -> list[bytes]:
        out: list[bytes] = []
        start = 0
        while True:
            nl = data.find(b"\n", start)
            if nl < 0:
                if not self._discard:
                    self._buf += data[start:]
                    if len(self._buf) > self.max_line:
                        out.append(bytes(self._buf[: self.max_line]))
                        self._buf = bytearray()
                        self._discard = True
                return out
            if self._discard:
                self._discard = False
            else:
                self._buf += data[start:nl]
                out.append(bytes(self._buf[: self.max_line]).rstrip(b"\r"))
                self._buf = bytearray()
            start = nl + 1

    def flush(self) -> list[bytes]:
        rest = bytes(self._buf).strip(b"\r")
        self._buf = bytearray()
        self._discard = False
        return [rest] if rest else []


class NmeaParser:
    """Checks lines strictly. ``accepted`` counts by sentence type, ``rejected`` by reason."""

    def __init__(self) -> None:
        self.accepted: Counter[str] = Counter()
        self.rejected: Counter[str] = Counter()
        self.lines = 0

    def parse(self, raw: bytes | str) -> Sentence | None:
        """One line. Returns None for a blank line or a ``#`` comment; never raises."""
        try:
            return self._parse(raw)
        except Exception:  # pynmea2 and our converters must never take the daemon down
            text = (
                raw.decode("ascii", "replace") if isinstance(raw, bytes | bytearray) else str(raw)
            )
            return self._reject(text, "parse_error")

    def _reject(self, text: str, reason: str) -> Sentence:
        self.rejected[reason] += 1
        return Sentence(text, False, reason)

    def _parse(self, raw: bytes | str) -> Sentence | None:
        if isinstance(raw, (bytes, bytearray)):
            raw = raw.strip()
            if not raw or raw[0] == 35:  # blank or a "#" comment
                return None
            try:
                text = raw.decode("ascii")
            except UnicodeDecodeError:
                self.lines += 1
                return self._reject(raw.decode("ascii", "replace"), "not_ascii")
        else:
            text = raw.strip()
            if not text or text[0] == "#":
                return None
        self.lines += 1
        if len(text) > MAX_LINE:
            return self._reject(text, "too_long")
        if not text.isprintable() or not text.isascii():
            return self._reject(text, "not_ascii")
        if text[0] not in "$!":
            return self._reject(text, "no_start")
        if text.find("$", 1) > 0 or text.find("!", 1) > 0:
            return self._reject(text, "spliced")
        star = text.rfind("*")
        if star < 0 or len(text) - star != 3:
            return self._reject(text, "no_checksum")
        if not text[star + 1 :].isalnum():
            return self._reject(text, "no_checksum")
        try:
            want = int(text[star + 1 :], 16)
        except ValueError:
            return self._reject(text, "no_checksum")
        if _xor(text[1:star]) != want:
            return self._reject(text, "bad_checksum")
        if text[0] == "!":  # AIS encapsulation: well-formed, not ours
            self.accepted["other"] += 1
            return Sentence(text, True, "", text[1:3], text[3:6], {})
        comma = text.find(",", 1, star)
        addr = text[1 : comma if comma > 0 else star]
        if not addr.isalnum():
            return self._reject(text, "parse_error")
        if addr[0] == "P" and 4 <= len(addr) <= 9:  # proprietary
            self.accepted["other"] += 1
            return Sentence(text, True, "", "P", addr[1:], {})
        if len(addr) != 5:
            return self._reject(text, "parse_error")
        if addr[2:] not in SPECS:  # well-formed, but a type we don't use: not checked further
            self.accepted["other"] += 1
            return Sentence(text, True, "", addr[:2], addr[2:], {})
        try:
            msg = pynmea2.parse(text)  # the checksum is already checked above
        except (pynmea2.ParseError, ValueError, TypeError, AttributeError):
            return self._reject(text, "parse_error")
        talker = getattr(msg, "talker", "") or ""
        stype = getattr(msg, "sentence_type", "") or ""
        data = list(getattr(msg, "data", []))
        spec = SPECS.get(stype)
        if spec is None:
            return self._reject(text, "parse_error")
        lo, hi, kinds = spec
        if not lo <= len(data) <= hi:
            return self._reject(text, "field_count")
        for kind, value in zip(kinds, data, strict=False):
            if not _check(kind, value.strip()):
                return self._reject(text, "bad_field")
        self.accepted[stype] += 1
        return Sentence(text, True, "", talker, stype, extract(stype, [v.strip() for v in data]))

    def counters(self) -> dict[str, Any]:
        return {
            "lines": self.lines,
            "accepted": sum(self.accepted.values()),
            "rejected": sum(self.rejected.values()),
            "accepted_by_type": dict(self.accepted),
            "rejected_by_reason": dict(self.rejected),
        }


def depth_below_surface(s: Sentence, offset_m: float) -> float | None:
    """Depth below the surface in metres from a DPT or DBT sentence (see compensation)."""
    if s.type not in ("DPT", "DBT"):
        return None
    return depth_below_surface_m(s.data.get("depth_m"), s.type, s.data.get("offset_m"), offset_m)
