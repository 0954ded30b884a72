"""NMEA 0183 fields read and written back the way the log wrote them, for ``bench/inject_nmea.py``.

A rewritten field keeps its number of decimals, its zero padding and an explicit ``+``, so a value
that comes out the same as the recorded one is the recorded text byte for byte. Latitude and
longitude keep their degree digits and minute decimals, and the hemisphere letter follows the sign.
A checksum is recomputed with the convention the line was written with: the standard XOR, or the
variant an instrument bus uses instead (forcemap.host.decode.nmea_checksum), in the same letter
case. Fields are read with plain string splitting, not with forcemap's parser, so the injection does
not lean on the code it tests.
"""

from __future__ import annotations

import calendar
import math

from forcemap.host.decode.nmea_checksum import VARIANTS, variant_of, xor

STANDARD = "standard"


class Unreadable(ValueError):
    """A field that is not the number its sentence says it is: the sentence is left as recorded."""


def num(text: str) -> float | None:
    """A numeric field; None when empty; Unreadable when it is not a number."""
    if text == "":
        return None
    try:
        v = float(text)
    except ValueError:
        raise Unreadable(text) from None
    if not math.isfinite(v):
        raise Unreadable(text)
    return v


def number_like(old: str, value: float) -> str:
    """``value`` written as ``old`` was: its decimals, zero padding and explicit sign."""
    body = old.lstrip("+-")
    ip, dot, fp = body.partition(".")
    dec = len(fp)
    text = f"{abs(value):.{dec}f}"
    i2, _, f2 = text.partition(".")
    if len(ip) > 1 and ip.startswith("0"):
        i2 = i2.zfill(len(ip))
    elif ip == "" and i2 == "0":
        i2 = ""
    if float(text) == 0.0:  # no sign of its own: the recorded one ("-0.0" stays "-0.0")
        sign = old[0] if old[:1] in ("+", "-") else ""
    else:
        sign = "-" if value < 0 else ("+" if old.startswith("+") else "")
    return sign + i2 + (("." + f2) if dec else dot)


def angle_like(old: str, deg: float) -> str:
    """A compass or relative angle in [0, 360) written as ``old`` was (359.96 to 1 decimal: 0.0)."""
    dec = len(old.partition(".")[2])
    r = round(deg % 360.0, dec)
    if r >= 360.0:
        r -= 360.0
    return number_like(old, r)


def read_latlon(text: str, hemi: str) -> float | None:
    """``ddmm.mmmm`` (or ``dddmm.mmmm``) and N/S/E/W to signed degrees; None when empty."""
    if text == "" or hemi == "":
        return None
    v = num(text)
    if v is None or hemi.upper() not in "NSEW":
        raise Unreadable(text + hemi)
    deg = math.floor(v / 100.0)
    value = deg + (v - 100.0 * deg) / 60.0
    return -value if hemi.upper() in "SW" else value


def latlon_like(old: str, old_hemi: str, value: float, axis: str) -> tuple[str, str]:
    """Signed degrees written as ``old`` was: its degree digits and minute decimals, and the
    hemisphere letter ("lat": N/S, "lon": E/W) that goes with the sign."""
    ip, _, fp = old.partition(".")
    dec = len(fp)
    scale = 10**dec
    units = round(abs(value) * 60.0 * scale)
    deg, rem = divmod(units, 60 * scale)
    mins, frac = divmod(rem, scale)
    text = f"{deg:0{max(len(ip) - 2, 1)}d}{mins:02d}" + (f".{frac:0{dec}d}" if dec else "")
    positive = "N" if axis == "lat" else "E"
    negative = "S" if axis == "lat" else "W"
    hemi = positive if value >= 0 else negative
    if old_hemi.islower():
        hemi = hemi.lower()
    if text == old and hemi.upper() == old_hemi.upper():
        return old, old_hemi
    return text, hemi


def checksum_convention(body: str, given: str) -> str | None:
    """How ``given`` (two hex digits) was computed over ``body``: ``standard``, a variant's name,
    or None when it matches no convention (a damaged line)."""
    try:
        want = int(given, 16)
    except ValueError:
        return None
    if len(given) != 2:
        return None
    if xor(body) == want:
        return STANDARD
    return variant_of(body, want) or None


def checksum_for(body: str, convention: str, like: str) -> str:
    """The checksum of ``body`` by ``convention``, in the letter case of ``like``."""
    part = body if convention == STANDARD else VARIANTS[convention][1](body)
    text = f"{xor(part):02X}"
    return text.lower() if like.islower() else text


def tod_of(text: str) -> float | None:
    """``hhmmss[.sss]`` to seconds of the day; None when empty or not a time."""
    if len(text) < 6 or not text[:6].isdigit():
        return None
    try:
        frac = float(text[6:]) if len(text) > 6 else 0.0
    except ValueError:
        return None
    h, m, s = int(text[:2]), int(text[2:4]), int(text[4:6])
    if h > 23 or m > 59 or s > 60:
        return None
    return 3600.0 * h + 60.0 * m + s + frac


def split_sentence(line: bytes) -> tuple[bytes, str, str | None, bytes] | None:
    """(bytes before the last $, body, checksum or None, bytes after the checksum), or None if no
    sentence. A line with junk or a cut sentence before its last ``$`` keeps them as they are."""
    i = line.rfind(b"$")
    if i < 0:
        return None
    text = line[i:].decode("latin-1")
    core = text.rstrip("\r")
    eol = text[len(core) :]
    star = core.rfind("*")
    if star < 0:
        return line[:i], core[1:], None, eol.encode("latin-1")
    tail = (core[star + 3 :] + eol).encode("latin-1")
    return line[:i], core[1:star], core[star + 1 : star + 3], tail


def date_of(stype: str, f: list[str]) -> float | None:
    """The UNIX time of 00:00 UTC of an RMC's or ZDA's date, if it has one."""
    try:
        if stype == "RMC" and len(f) > 8 and len(f[8]) == 6:
            d, m, y = int(f[8][:2]), int(f[8][2:4]), int(f[8][4:])
            y += 2000 if y < 80 else 1900
        elif stype == "ZDA" and len(f) > 3 and f[1] and f[2] and f[3]:
            d, m, y = int(f[1]), int(f[2]), int(f[3])
        else:
            return None
        return float(calendar.timegm((y, m, d, 0, 0, 0)))
    except (ValueError, OverflowError):
        return None
