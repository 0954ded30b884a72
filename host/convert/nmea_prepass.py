"""What an NMEA import learns from the whole file before the pipeline reads it line by line.

Three things: a UTC time for every line (forcemap.host.convert.importers' docstring says how); where
the boat's track is (the median of every fix and the radius it spans), so that position jumps at the
very start of a log are told from the track (forcemap.host.fuse.position_jumps); and, when no time
sentence was accepted, what rejected them, so the error names the cause (a checksum variant, with the
option that accepts it) rather than saying the log has no time.

The calibrated import reads a capture twice (forcemap.host.convert.self_calibration): inside ``kept()``
the second pass takes the first one's lines, times and track instead of reading them again (on the
7.4-hour San Francisco Bay log, about 4 s of the import's 51 s of CPU).
"""

from __future__ import annotations

import contextlib
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from forcemap.host.convert.capture_file import capture_lines
from forcemap.host.decode import nmea_checksum
from forcemap.host.decode.nmea import NmeaParser
from forcemap.host.fuse.position_jumps import track_seed

TIME_TYPES = (b"RMC,", b"GGA,", b"GLL,", b"ZDA,")
POSITION_TYPES = (b"RMC,", b"GGA,", b"GLL,")
DAY = 86400.0


@dataclass(frozen=True)
class Prepass:
    """A capture's lines, the notes reading it gave, each line's UNIX time and how it was found, and
    the track's seed (None without UTC or without a fix)."""

    lines: list[bytes]
    notes: list[str]
    times: list[float]
    how: str
    seed: tuple[float, float, float] | None

    @property
    def has_time(self) -> bool:
        return not self.how.startswith("no UTC")


_kept: dict[tuple[str, str, float | None], Prepass] | None = None


@contextlib.contextmanager
def kept() -> Iterator[None]:
    """Within it, each capture's pre-pass is made once and kept; it is dropped when the block ends."""
    global _kept
    outer, _kept = _kept, ({} if _kept is None else _kept)
    try:
        yield
    finally:
        _kept = outer


def prepass(path: str | Path, checksum: str = "strict", day: float | None = None) -> Prepass:
    """Read ``path``'s lines, time them and find its track (once per ``kept()`` block). ``day``: the
    UNIX time of the UTC midnight the log starts on, for a log whose sentences carry no date."""
    key = (str(path), checksum, day)
    if _kept is not None and key in _kept:
        return _kept[key]
    notes: list[str] = []
    lines = capture_lines(path, notes)
    times, how = nmea_line_times(lines, checksum, day)
    seed = position_seed(lines, checksum) if not how.startswith("no UTC") else None
    out = Prepass(lines, notes, times, how, seed)
    if _kept is not None:
        _kept[key] = out
    return out


def nmea_line_times(
    lines: list[bytes], checksum: str = "strict", day: float | None = None
) -> tuple[list[float], str]:
    """A UNIX time for every line (see the module docstring) and how it was found; ``day`` (the UTC
    midnight the log starts on, `import --date`) dates a log whose sentences carry no date."""
    parser = NmeaParser(checksum)
    tods: list[tuple[int, float]] = []
    date0: float | None = None
    for i, line in enumerate(lines):
        if not any(k in line for k in (b"RMC,", b"GGA,", b"GLL,", b"ZDA,")):
            continue
        s = parser.parse(line)
        if s is None or not s.valid or s.data.get("tod") is None:
            continue
        tod = s.data["tod"]
        if date0 is None and s.data.get("utc") is not None:
            date0 = s.data["utc"] - tod
        tods.append((i, tod))
    n = len(lines)
    if not tods:
        return [float(i) for i in range(n)], "no UTC in the file: 1 s per line from 1970-01-01"
    base = date0 if date0 is not None else (day or 0.0)
    anchors: list[tuple[int, float]] = []
    past = 0.0  # the days gone by since the first time sentence
    prev_tod = None
    for i, tod in tods:
        if prev_tod is not None and tod < prev_tod - DAY / 2:
            past += DAY  # past midnight
        t = base + past + tod
        prev_tod = tod
        if anchors and not (anchors[-1][1] < t <= anchors[-1][1] + 3600.0):
            continue  # not moving forward, or a corrupt stamp
        anchors.append((i, t))
    if len(anchors) >= 2 and anchors[-1][0] > anchors[0][0]:
        rate = (anchors[-1][1] - anchors[0][1]) / (anchors[-1][0] - anchors[0][0])
    else:
        rate = 1.0
    times = [0.0] * n
    k = 0
    for i in range(n):
        while k + 1 < len(anchors) and anchors[k + 1][0] <= i:
            k += 1
        i0, t0 = anchors[k]
        if i < i0:
            times[i] = t0 - (i0 - i) * rate
        elif k + 1 < len(anchors):
            i1, t1 = anchors[k + 1]
            times[i] = t0 + (t1 - t0) * (i - i0) / (i1 - i0)
        else:
            times[i] = t0 + (i - i0) * rate
    return times, "UTC anchors from RMC/GGA/GLL/ZDA" + date_note(date0, day)


def iso(t: float) -> str:
    """The UTC day of a UNIX time, YYYY-MM-DD."""
    return time.strftime("%Y-%m-%d", time.gmtime(t))


def date_note(date0: float | None, day: float | None) -> str:
    """Where the log's day came from: its own RMC or ZDA (and a --date that disagrees, not used), the
    user's --date, or nowhere (1970-01-01, and what that day gets wrong)."""
    if date0 is not None:
        if day is not None and iso(day) != iso(date0):
            return f"; the file's own date ({iso(date0)}) is used, not --date {iso(day)}"
        return ""
    if day is not None:
        return f", no date in the file: the day from --date, {iso(day)}"
    return (
        ", no date in the file: 1970-01-01 (the magnetic declination, tides and --at need the day: "
        "give it with --date YYYY-MM-DD)"
    )


def position_seed(
    lines: list[bytes], checksum: str = "strict"
) -> tuple[float, float, float] | None:
    """(lat, lon, radius m) of the boat's track from every valid fix in ``lines``, or None."""
    parser = NmeaParser(checksum)
    fixes = []
    for line in lines:
        if not any(k in line for k in POSITION_TYPES):
            continue
        s = parser.parse(line)
        if s is None or not s.valid or s.data.get("lat") is None or s.data.get("lon") is None:
            continue
        if s.type == "GGA" and not s.data.get("quality"):
            continue
        if s.type != "GGA" and s.data.get("status") != "A":
            continue
        fixes.append((s.data["lat"], s.data["lon"]))
    return track_seed(fixes)


def why_no_time(lines: list[bytes], name: str, checksum: str = "strict") -> str:
    """The one line for a capture from which no UTC was read: what rejected its time sentences."""
    parser = NmeaParser(checksum)
    kinds: Counter[str] = Counter()
    for line in lines:
        hit = next((k for k in TIME_TYPES if k in line), None)
        if hit is None:
            continue
        s = parser.parse(line)
        if s is not None and not s.valid:
            kinds[hit[:3].decode()] += 1
    if not kinds:
        return f"{name}: no time in this log (no NMEA RMC, GGA, GLL or ZDA with UTC)"
    which = ", ".join(f"{n} {k}" for k, n in kinds.most_common())
    reasons = ", ".join(f"{r} {n}" for r, n in parser.rejected.most_common())
    out = f"{name}: no time accepted from this log: its {which} lines were all rejected ({reasons})"
    found = nmea_checksum.systematic(parser.variants, parser.rejected["bad_checksum"])
    if found and checksum == "strict":
        variant, n = found[0]
        out += (
            f"; {n} of them have their checksum computed {nmea_checksum.describe(variant)}, a "
            "systematic variant: import with --nmea-checksum lenient to accept them"
        )
    return out


def finding_notes(findings: list) -> list[str]:
    """The import's note for each quality finding that is not green (its one line)."""
    return [f.message for f in findings if f.verdict != "green"]
