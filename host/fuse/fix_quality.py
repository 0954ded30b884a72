"""How good a position source's fix is, and which of two receivers is the better by it.

A receiver says so in several places: GGA's quality indicator and HDOP, GSA's fix type (2D, 3D) and
HDOP, the mode indicator of RMC and GLL (NMEA 2.3: autonomous, differential, RTK, estimated), and
MAVLink's GPS_RAW_INT (fix type, and eph: the HDOP x 100). Each is mapped to one fix class, from
"no fix" to "RTK fixed"; a receiver's class is the best its sentences of the last QUALITY_AGE_S
report (GGA says DGPS where an older receiver's RMC only says A), its HDOP the median of those it
reported in that time (one odd value does not rank a receiver).

Two receivers are ranked by their fix class first, then by HDOP when one is clearly worse (more than
HDOP_RATIO times the other's and HDOP_MIN_DIFF more: 2.1 against 0.9, not 1.1 against 0.9); a
receiver that says nothing of its fix is not ranked by it, and the other rules decide
(forcemap.host.fuse.sources).
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from dataclasses import dataclass, field

FIX_NAMES = ("no fix", "estimated", "2D", "GPS", "DGPS", "RTK float", "RTK fixed")
NO_FIX, ESTIMATED, FIX_2D, GPS, DGPS, RTK_FLOAT, RTK_FIXED = range(len(FIX_NAMES))
# GGA quality indicator: 3 is a PPS fix, 6 dead reckoning, 7 manual input, 8 simulation
GGA_QUALITY = {
    0: NO_FIX,
    1: GPS,
    2: DGPS,
    3: GPS,
    4: RTK_FIXED,
    5: RTK_FLOAT,
    6: ESTIMATED,
    7: NO_FIX,
    8: NO_FIX,
}
# RMC, GLL, GNS mode indicator (NMEA 2.3): P precise, M manual, S simulator, N no fix
MODE = {
    "A": GPS,
    "D": DGPS,
    "P": DGPS,
    "F": RTK_FLOAT,
    "R": RTK_FIXED,
    "E": ESTIMATED,
    "M": NO_FIX,
    "S": NO_FIX,
    "N": NO_FIX,
}
GSA_FIX = {1: NO_FIX, 2: FIX_2D, 3: GPS}
# MAVLink GPS_FIX_TYPE: 7 static (a base station), 8 PPP
MAV_FIX = {
    0: NO_FIX,
    1: NO_FIX,
    2: FIX_2D,
    3: GPS,
    4: DGPS,
    5: RTK_FLOAT,
    6: RTK_FIXED,
    7: GPS,
    8: DGPS,
}
QUALITY_AGE_S = 10.0
HDOP_RATIO = 1.5
HDOP_MIN_DIFF = 0.5
HDOP_KEEP = 64  # HDOP reports kept per receiver: over QUALITY_AGE_S at 5 Hz from GGA and GSA

Quality = tuple[int | None, float | None]  # (fix class or None, HDOP or None)


@dataclass
class FixReports:
    """What one receiver's sentences said of its fix: by sentence, (time, class) and (time, HDOP)."""

    fix: dict[str, tuple[float, int]] = field(default_factory=dict)
    hdop: deque[tuple[float, float]] = field(default_factory=lambda: deque(maxlen=HDOP_KEEP))
    latest: float = -math.inf

    def report(self, kind: str, t: float, fix: int | None, hdop: float | None) -> None:
        if fix is not None:
            self.fix[kind] = (t, fix)
            self.latest = max(self.latest, t)
        if hdop is not None and hdop > 0:
            self.hdop.append((t, hdop))
            self.latest = max(self.latest, t)

    def current(self) -> Quality:
        """The best class reported in the last QUALITY_AGE_S, the median HDOP of that time."""
        since = self.latest - QUALITY_AGE_S
        fixes = [c for t, c in self.fix.values() if t >= since]
        hdops = [h for t, h in self.hdop if t >= since]
        return (max(fixes) if fixes else None), (statistics.median(hdops) if hdops else None)


def describe(q: Quality) -> str:
    """``DGPS, HDOP 0.9``; ``GPS``; ``HDOP 1.2``; empty when nothing is known."""
    fix, hdop = q
    parts = ([FIX_NAMES[fix]] if fix is not None else []) + (
        [f"HDOP {hdop:.1f}"] if hdop is not None else []
    )
    return ", ".join(parts)


def compare(a: Quality, b: Quality) -> int:
    """Negative if ``a`` is the better fix, positive if ``b`` is, 0 if their fixes do not decide."""
    if a[0] is not None and b[0] is not None and a[0] != b[0]:
        return b[0] - a[0]
    ha, hb = a[1], b[1]
    if ha is None or hb is None:
        return 0
    if ha > HDOP_RATIO * hb and ha - hb >= HDOP_MIN_DIFF:
        return 1
    if hb > HDOP_RATIO * ha and hb - ha >= HDOP_MIN_DIFF:
        return -1
    return 0


def gga_fix(quality: int | None) -> int | None:
    return None if quality is None else GGA_QUALITY.get(quality)


def mode_fix(mode: str | None) -> int | None:
    return MODE.get(mode.upper()) if mode else None


def gsa_fix(fix_type: int | None) -> int | None:
    return None if fix_type is None else GSA_FIX.get(fix_type)


def mav_fix(fix_type: int | None) -> int | None:
    return None if fix_type is None else MAV_FIX.get(fix_type)
