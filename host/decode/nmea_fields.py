"""NMEA 0183 field values in SI: one extractor per sentence type, for sentences already checked."""

from __future__ import annotations

import datetime as _dt
import math
from typing import Any

from forcemap.host.vessel.geodesy import wrap_to_180

KNOT = 1852.0 / 3600.0
KMH = 1000.0 / 3600.0
FOOT = 0.3048
FATHOM = 1.8288

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
    "ROT": (2, 2, ("f", "=AV")),
    "HDM": (2, 2, ("f", "=M")),
    "HDG": (5, 5, ("f", "f", "=EW", "f", "=EW")),
    "VHW": (8, 8, ("f", "=T", "f", "=M", "f", "=N", "f", "=K")),
    "MWV": (5, 5, ("f", "=RT", "f", "=KMNS", "=AV")),
    "VWR": (8, 8, ("f", "=LR", "f", "=N", "f", "=M", "f", "=K")),
    "MWD": (8, 8, ("f", "=T", "f", "=M", "f", "=N", "f", "=M")),
    "ZDA": (6, 6, ("t", "i", "i", "i", "i", "i")),
    "GLL": (6, 7, ("lat", "=NS", "lon", "=EW", "t", "=AV", "=ADENSMFRP")),
    # XDR: groups of (type, value, unit, name); an attitude is type A, unit D
    "XDR": (3, 40, ("s", "s", "s", "s") * 10),
    # GSA: mode, fix type, 12 satellite numbers, PDOP, HDOP, VDOP (and NMEA 4.10's system id)
    "GSA": (17, 18, ("=AM", "i", *("s",) * 12, "f", "f", "f", "s")),
}


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
        "mode": d[11].upper() or None,
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
        "mode": d[6].upper() or None,
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


def _rot(d: list[str]) -> dict[str, Any]:
    """Rate of turn: degrees per minute, negative to port; here deg/s."""
    r = _f(d[0])
    return {"yaw_rate": None if r is None else r / 60.0, "status": d[1].upper() or None}


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
        "angle": None if a is None else wrap_to_180(a),
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
    return {"angle": None if a is None else wrap_to_180(a), "speed": sp}


def _mwd(d: list[str]) -> dict[str, Any]:
    sp = _first_speed((d[4], "N"), (d[6], "M"))
    return {"dir": _f(d[0]), "dir_mag": _f(d[2]), "speed": sp}


def _gsa(d: list[str]) -> dict[str, Any]:
    return {"fix_type": int(d[1]) if d[1] else None, "hdop": _f(d[15])}


# transducer names real logs use for the hull's attitude (B&G/NKE HEEL and TRIM, NMEA 4 ROLL and PTCH)
ROLL_NAMES = ("ROLL", "HEEL")
PITCH_NAMES = ("PTCH", "PITCH", "TRIM")


def _num_or_none(s: str) -> float | None:
    try:
        x = float(s)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


def _xdr(d: list[str]) -> dict[str, Any]:
    """The hull's roll and pitch (deg; roll positive starboard down, pitch bow up) from a
    transducer sentence's angular groups (type A, unit D), None where it has neither."""
    out: dict[str, Any] = {"roll": None, "pitch": None}
    for i in range(0, len(d) - 3, 4):
        kind, value, unit, name = d[i : i + 4]
        if kind.upper() != "A" or unit.upper() not in ("D", ""):
            continue
        key = name.upper().strip()
        if key in ROLL_NAMES and out["roll"] is None:
            out["roll"] = _num_or_none(value)
        elif key in PITCH_NAMES and out["pitch"] is None:
            out["pitch"] = _num_or_none(value)
    return out


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
    "ROT": _rot,
    "HDM": _hdm,
    "HDG": _hdg,
    "VHW": _vhw,
    "MWV": _mwv,
    "VWR": _vwr,
    "MWD": _mwd,
    "ZDA": _zda,
    "GSA": _gsa,
    "XDR": _xdr,
}


def extract(stype: str, d: list[str]) -> dict[str, Any]:
    """SI values from a validated sentence's fields (see SPECS). Missing fields are None."""
    fn = EXTRACTORS.get(stype)
    if fn is None:
        return {}
    return fn(d + [""] * (SPECS[stype][1] - len(d)))
