"""What an NMEA import learns from the whole file before the pipeline reads it line by line.

Two things: where the boat's track is (the median of every fix and the radius it spans), so that
position jumps at the very start of a log are told from the track (forcemap.host.fuse.position_jumps);
and, when no time sentence was accepted, what rejected them, so the error names the cause (a
checksum variant, with the option that accepts it) rather than saying the log has no time.
"""

from __future__ import annotations

from collections import Counter

from forcemap.host.decode import nmea_checksum
from forcemap.host.decode.nmea import NmeaParser
from forcemap.host.fuse.position_jumps import track_seed

TIME_TYPES = (b"RMC,", b"GGA,", b"GLL,", b"ZDA,")
POSITION_TYPES = (b"RMC,", b"GGA,", b"GLL,")


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
