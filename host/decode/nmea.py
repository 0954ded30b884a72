"""NMEA 0183: split lines from any chunking, check them strictly, extract SI values. Never raises."""

from __future__ import annotations

import contextlib
import math
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pynmea2
from forcemap.host.decode import nmea_checksum
from forcemap.host.decode.nmea_fields import KNOT, SPECS, extract

__all__ = ["KNOT", "LineSplitter", "NmeaParser", "Sentence", "depth_below_surface", "extract"]

MAX_LINE = 120  # NMEA allows 82 characters; real talkers overrun a little
# the lines parsed in the current `parsed_once()` block: (checksum mode, line) -> (sentence, its counts)
_memo: dict | None = None
_COUNTERS = ("accepted", "rejected", "variants", "variant_addresses")


@contextlib.contextmanager
def parsed_once() -> Iterator[None]:
    """Within it, a parser made there parses each distinct line once per checksum mode: an import reads
    its capture in a pre-pass and then twice (forcemap.host.convert.nmea_prepass ``kept``). A line parsed
    again gives a new Sentence equal to the first and counts in its parser as the first did."""
    global _memo
    outer, _memo = _memo, ({} if _memo is None else _memo)
    try:
        yield
    finally:
        _memo = outer


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
    """Checks lines strictly. ``accepted`` counts by sentence type, ``rejected`` by reason.

    ``checksum``: "strict" rejects every checksum that fails; "lenient" also accepts a checksum
    computed by one of the variants of forcemap.host.decode.nmea_checksum. Either way the lines
    whose checksum matches a variant are counted by variant (``variants``) and by address.
    """

    def __init__(self, checksum: str = "strict") -> None:
        if checksum not in nmea_checksum.MODES:
            raise ValueError(f"checksum must be one of {nmea_checksum.MODES}, not {checksum!r}")
        self.checksum = checksum
        self.accepted: Counter[str] = Counter()
        self.rejected: Counter[str] = Counter()
        self.variants: Counter[str] = Counter()  # lines whose checksum is a variant's, by variant
        self.variant_addresses: Counter[str] = Counter()  # ... by "variant address"
        self.lines = 0
        self._memo = _memo

    def parse(self, raw: bytes | str) -> Sentence | None:
        """One line. Returns None for a blank line or a ``#`` comment; never raises."""
        if self._memo is None:
            return self._parse_safely(raw)
        key = (self.checksum, bytes(raw) if isinstance(raw, bytearray) else raw)
        hit = self._memo.get(key)
        if hit is None:
            hit = self._memo[key] = self._recorded(raw)
        s, lines, counts = hit
        self.lines += lines
        for name, c in counts:
            getattr(self, name).update(c)
        return None if s is None else Sentence(s.text, s.valid, s.reason, s.talker, s.type, dict(s.data))

    def _recorded(self, raw: bytes | str) -> tuple[Sentence | None, int, tuple]:
        """`raw` parsed, and what it added to the parser's counts (`parsed_once`)."""
        kept = [getattr(self, name) for name in _COUNTERS], self.lines
        for name in _COUNTERS:
            setattr(self, name, Counter())
        self.lines = 0
        try:
            s = self._parse_safely(raw)
            counts = tuple((n, dict(getattr(self, n))) for n in _COUNTERS if getattr(self, n))
            return s, self.lines, counts
        finally:
            for name, c in zip(_COUNTERS, kept[0], strict=True):
                setattr(self, name, c)
            self.lines = kept[1]

    def _parse_safely(self, raw: bytes | str) -> Sentence | None:
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
        lenient = _xor(text[1:star]) != want
        if lenient and not self._variant(text[1:star], want):
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
        if comma > 0 and addr[0] not in "Pp" and text.count("*") == 1:
            # what pynmea2.parse gives for such a line (one "*", a talker sentence of a type it
            # knows), without its regular expression and sentence object: the bulk of a log
            talker, stype, data = addr[:2].upper(), addr[2:], text[comma + 1 : star].split(",")
        else:
            try:
                # the checksum is already checked above (pynmea2 would refuse a variant's)
                msg = pynmea2.parse(text[:star] if lenient else text)
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

    def _variant(self, body: str, want: int) -> bool:
        """Count a checksum computed by a known variant; True if lenient parsing accepts it."""
        variant = nmea_checksum.variant_of(body, want)
        if not variant:
            return False
        self.variants[variant] += 1
        self.variant_addresses[f"{variant} {body.split(',', 1)[0]}"] += 1
        return self.checksum == "lenient"

    def counters(self) -> dict[str, Any]:
        return {
            "lines": self.lines,
            "checksum": self.checksum,
            "checksum_variants": dict(self.variants),
            "accepted": sum(self.accepted.values()),
            "rejected": sum(self.rejected.values()),
            "accepted_by_type": dict(self.accepted),
            "rejected_by_reason": dict(self.rejected),
        }


def depth_below_surface_m(
    depth_m: float | None, kind: str, sentence_offset_m: float | None, transducer_offset_m: float
) -> float | None:
    """Water depth below the surface from DPT or DBT.

    DPT's own offset is used when positive (transducer to waterline); negative (to the keel) or empty
    falls back to the calibration's transducer depth. DBT is below the transducer: add that depth.
    """
    if depth_m is None:
        return None
    if kind == "DPT" and sentence_offset_m is not None and sentence_offset_m > 0:
        return depth_m + sentence_offset_m
    return depth_m + transducer_offset_m


def depth_below_surface(s: Sentence, offset_m: float) -> float | None:
    """Depth below the surface in metres from a DPT or DBT sentence (see depth_below_surface_m)."""
    if s.type not in ("DPT", "DBT"):
        return None
    return depth_below_surface_m(s.data.get("depth_m"), s.type, s.data.get("offset_m"), offset_m)
