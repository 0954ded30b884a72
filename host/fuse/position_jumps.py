"""Position jumps: fixes that imply a speed no boat has, flagged with their reason and left out.

A receiver that starts with a stale almanac, a multiplexer that splices a test sentence into the
stream, or a second device looping a recorded position puts fixes kilometres off the boat's track.
Physics gives them away: the boat cannot have covered the distance in the time. A fix is a jump
when it lies farther from the last good fix (of any receiver: the boat has one position) than
MAX_SPEED_MPS times the time between them plus SLACK_M (receiver error, antenna offsets, a late
sentence). A jump is not used for the boat's state; it is counted, and the stretches of jumps are
listed with their times, their distance and the speed they imply (``QaFinding`` ``qa.position.jumps``).

Which track is the boat's? The first good fix sets it, or, in an import, the ``seed``: the median of
every fix in the file with the radius the track spans, so that a log which opens with a minute of
fixes 500 km away keeps its real track. Should the track that is left out run on by itself,
consistent, with no good fix between, for RESET_S or for longer than the track before it had lasted
(at least MIN_RESET_S: a live run has no pre-pass, and a receiver may open with a minute of stale
fixes), it becomes the track, and that is said too.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from forcemap.host.log.qa_records import QaFinding

MAX_SPEED_MPS = 25.0  # 49 kn: faster than the boats forcemap maps, slower than any jump
SLACK_M = 100.0
RESET_S = 120.0
MIN_RESET_S = 10.0
EARTH_M = 6_371_000.0
RED_SHARE = 0.05  # over this share of fixes are jumps: the position source is not to be trusted
KNOT = 1852.0 / 3600.0


def distance_m(lat0: float, lon0: float, lat1: float, lon1: float) -> float:
    """Great-circle distance in metres (haversine)."""
    p0, p1 = math.radians(lat0), math.radians(lat1)
    a = (
        math.sin((p1 - p0) / 2) ** 2
        + math.cos(p0) * math.cos(p1) * math.sin(math.radians(lon1 - lon0) / 2) ** 2
    )
    return 2.0 * EARTH_M * math.asin(min(1.0, math.sqrt(a)))


@dataclass
class Stretch:
    """A run of jumps: when (UTC s), how many, how far from the track and how fast that would be."""

    t0: float
    t1: float
    n: int
    km: float
    speed_mps: float

    def text(self) -> str:
        a = time.strftime("%H:%M:%S", time.gmtime(self.t0))
        b = time.strftime("%H:%M:%S", time.gmtime(self.t1))
        speed = f" ({self.speed_mps / KNOT:.3g} kn)" if self.speed_mps > 0 else ""
        return f"{a}-{b} UTC: {self.n} fixes up to {self.km:.3g} km off the track{speed}"


class JumpFilter:
    """Decides, fix by fix, whether a position is a jump from the boat's track."""

    def __init__(self) -> None:
        self.anchor: tuple[float, float, float] | None = None  # t, lat, lon of the last good fix
        self.track_t0 = 0.0  # host time the track began (its first good fix)
        self.seed_at: tuple[float, float, float] | None = None  # lat, lon, radius m
        self.run: list[tuple[float, float, float, float]] = []  # the jumps since the last good fix
        self.fixes = 0
        self.jumps = 0
        self.resets: list[float] = []  # UTC of each re-anchoring
        self.stretches: list[Stretch] = []

    def seed(self, lat: float, lon: float, radius_m: float) -> None:
        """Where the track is before any fix was judged good (an import's pre-pass)."""
        self.seed_at = (lat, lon, max(radius_m, SLACK_M))

    def is_jump(self, t: float, lat: float, lon: float, utc: float) -> bool:
        """Whether the fix at host time ``t`` (UTC ``utc``) is a jump; counts and lists it."""
        self.fixes += 1
        if self.anchor is None:
            if self.seed_at is None:
                self.anchor, self.track_t0 = (t, lat, lon), t
                return False
            d = distance_m(self.seed_at[0], self.seed_at[1], lat, lon)
            ok, speed = d <= self.seed_at[2], math.inf
        else:
            d = distance_m(self.anchor[1], self.anchor[2], lat, lon)
            dt = max(t - self.anchor[0], 0.0)
            ok = d <= MAX_SPEED_MPS * dt + SLACK_M
            speed = d / dt if dt > 0 else math.inf
        if ok:
            if self.anchor is None:
                self.track_t0 = t
            self.anchor, self.run = (t, lat, lon), []
            return False
        if self._moved(t, lat, lon):
            self.resets.append(utc)
            self.anchor, self.run, self.track_t0 = (t, lat, lon), [], self.run[0][0]
            return False
        self.jumps += 1
        self.run.append((t, lat, lon, utc))
        self._note(utc, d, speed)
        return True

    def _moved(self, t: float, lat: float, lon: float) -> bool:
        """The jumps since the last good fix are one consistent track for RESET_S, ending here."""
        if self.anchor is None or not self.run:
            return False
        lasted = self.anchor[0] - self.track_t0
        if t - self.run[0][0] < min(RESET_S, max(lasted, MIN_RESET_S)):
            return False
        pts = [*self.run, (t, lat, lon, 0.0)]
        return all(
            distance_m(a[1], a[2], b[1], b[2]) <= MAX_SPEED_MPS * max(b[0] - a[0], 0.0) + SLACK_M
            for a, b in zip(pts, pts[1:], strict=False)
        )

    def _note(self, utc: float, d: float, speed: float) -> None:
        last = self.stretches[-1] if self.stretches else None
        if last is not None and len(self.run) > 1:
            last.t1, last.n = utc, last.n + 1
            last.km = max(last.km, d / 1000.0)
            last.speed_mps = max(last.speed_mps, speed) if math.isfinite(speed) else last.speed_mps
        else:
            self.stretches.append(
                Stretch(utc, utc, 1, d / 1000.0, speed if math.isfinite(speed) else 0.0)
            )

    def finding(self) -> QaFinding | None:
        """``qa.position.jumps``: green with none, yellow when some were left out, red over RED_SHARE."""
        if not self.fixes:
            return None
        share = self.jumps / self.fixes
        verdict = "green" if not self.jumps else ("red" if share > RED_SHARE else "yellow")
        listed = "; ".join(s.text() for s in self.stretches[:5])
        more = f"; and {len(self.stretches) - 5} more stretches" if len(self.stretches) > 5 else ""
        if self.jumps:
            msg = (
                f"{self.jumps} of {self.fixes} position fixes flagged as jumps (an impossible speed "
                f"from the track) and left out, in {len(self.stretches)} stretch(es): {listed}{more}"
            )
        else:
            msg = f"no position jumps in {self.fixes} fixes"
        if self.resets:
            msg += f"; the track moved {len(self.resets)} time(s) and was followed"
        return QaFinding(
            "position",
            "jumps",
            verdict,
            msg,
            value=float(self.jumps),
            unit="fixes",
            threshold=f"a fix farther from the last good one than {MAX_SPEED_MPS:g} m/s x the time "
            f"between them + {SLACK_M:g} m is a jump; red over {RED_SHARE:.0%} of fixes",
            evidence=f"{self.fixes} fixes checked against the boat's track",
            fix="applied: jumps left out of the boat's state and the samples" if self.jumps else "",
            applied=bool(self.jumps),
            extra={
                "fixes": str(self.fixes),
                "stretches": listed + more,
                "resets_utc": " ".join(f"{t:.0f}" for t in self.resets),
            },
        )


def track_seed(fixes: list[tuple[float, float]]) -> tuple[float, float, float] | None:
    """The median of some fixes (lat, lon) and four times their median distance from it, plus a
    kilometre: where the boat's track is, in a pre-pass over a whole file (None for no fixes). A
    track along a line of length L from its middle: median distance L/4, so the radius holds it
    all; fixes off the track, as long as they are fewer than half, move neither."""
    if not fixes:
        return None
    lats = sorted(f[0] for f in fixes)
    lons = sorted(f[1] for f in fixes)
    lat, lon = lats[len(lats) // 2], lons[len(lons) // 2]
    d = sorted(distance_m(lat, lon, a, b) for a, b in fixes)
    return lat, lon, 4.0 * d[len(d) // 2] + 1000.0
