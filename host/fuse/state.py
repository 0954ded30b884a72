"""Boat state at any instant: interpolated (default) or the paper's nearest-neighbour ApproximateTime.

Why interpolation: at 4 Hz samples and 5-10 Hz autopilot messages, the nearest neighbour is up to
half an autopilot period away (50-100 ms, more after a dropped message). Turning at 20 deg/s that is
1-2 deg of heading error, which rotates the apparent wind (20 m/s) by 0.35-0.7 m/s; accelerating,
the boat velocity is off by a/2 * 0.1 s. Interpolating at the sample's own time removes that error
to second order, and circular interpolation keeps heading right across north. ApproximateTime also
pairs each sample with whichever message is closest even when the gap is seconds long; here no state
is given across a gap longer than ``max_gap_s``.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from dataclasses import dataclass
from typing import Any

from forcemap.host.vessel.geodesy import to_direction, velocity, wrap360, wrap_to_180

SYNC_MODES = ("interpolate", "approximate")
# without a rate-of-turn source, the yaw rate is the least-squares slope of one heading source over
# this window: a two-point difference of a 10 Hz fluxgate with 2 deg noise swings by 30 deg/s
YAW_WINDOW_S = 2.0


@dataclass(slots=True)
class FusedBoatState:
    """The boat at one instant. Angles in degrees (compass / deg per s), speeds in m/s."""

    t: float
    lat: float | None = None
    lon: float | None = None
    v_east: float | None = None
    v_north: float | None = None
    heading: float | None = None
    yaw_rate: float | None = None
    throttle: float | None = None

    @property
    def sog(self) -> float | None:
        if self.v_east is None or self.v_north is None:
            return None
        return math.hypot(self.v_east, self.v_north)

    @property
    def cog(self) -> float | None:
        if self.v_east is None or self.v_north is None:
            return None
        return to_direction(self.v_east, self.v_north)

    def as_message(self) -> dict[str, Any]:
        return {
            "t": self.t,
            "lat": self.lat,
            "lon": self.lon,
            "v_east": self.v_east,
            "v_north": self.v_north,
            "sog": self.sog,
            "cog": self.cog,
            "heading": self.heading,
            "yaw_rate": self.yaw_rate,
            "throttle": self.throttle,
        }


class Series:
    """Time-ordered samples of one quantity (tuples of floats), trimmed to a time window."""

    __slots__ = ("t", "v", "keep_s", "circular")

    def __init__(self, keep_s: float = 120.0, circular: tuple[int, ...] = ()) -> None:
        self.t: list[float] = []
        self.v: list[tuple] = []
        self.keep_s = keep_s
        self.circular = circular

    def add(self, t: float, value: tuple) -> None:
        if self.t and t < self.t[-1]:
            i = bisect_left(self.t, t)
            self.t.insert(i, t)
            self.v.insert(i, value)
        else:
            self.t.append(t)
            self.v.append(value)
        if len(self.t) > 64 and self.t[-1] - self.t[0] > 2 * self.keep_s:
            cut = bisect_left(self.t, self.t[-1] - self.keep_s)
            del self.t[:cut]
            del self.v[:cut]

    @property
    def last_t(self) -> float | None:
        return self.t[-1] if self.t else None

    def clear(self) -> None:
        self.t.clear()
        self.v.clear()

    def interpolate(self, t: float, max_gap: float) -> tuple | None:
        ts = self.t
        n = len(ts)
        if n == 0:
            return None
        i = bisect_left(ts, t)
        if i < n and ts[i] == t:
            return self.v[i]
        if i == 0 or i == n:
            return None
        t0, t1 = ts[i - 1], ts[i]
        if t1 - t0 > max_gap:
            return None
        f = (t - t0) / (t1 - t0)
        a, b = self.v[i - 1], self.v[i]
        out = []
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            if x is None or y is None:
                out.append(x if f < 0.5 else y)
            elif k in self.circular:
                out.append(wrap360(x + wrap_to_180(y - x) * f))
            else:
                out.append(x + (y - x) * f)
        return tuple(out)

    def nearest(self, t: float, max_gap: float) -> tuple | None:
        ts = self.t
        n = len(ts)
        if n == 0:
            return None
        i = bisect_left(ts, t)
        best = None
        for j in (i - 1, i):
            if 0 <= j < n and (best is None or abs(ts[j] - t) < abs(ts[best] - t)):
                best = j
        if best is None or abs(ts[best] - t) > max_gap:
            return None
        return self.v[best]


class StateEstimator:
    """Collects the autopilot's (or NMEA's) navigation messages and answers ``at(t)``."""

    def __init__(
        self, sync: str = "interpolate", max_gap_s: float = 2.0, keep_s: float = 120.0
    ) -> None:
        if sync not in SYNC_MODES:
            raise ValueError(f"sync must be one of {SYNC_MODES}, got {sync!r}")
        self.sync = sync
        self.max_gap_s = max_gap_s
        # per series: a source slower than max_gap_s (a GNSS fixing every 4 s) widens its own
        self.gaps = {"position": max_gap_s, "heading": max_gap_s, "throttle": max_gap_s}
        self.position = Series(keep_s)  # (lat, lon, v_east, v_north)
        self.heading = Series(keep_s, circular=(0,))  # (heading_deg, yaw_rate_deg_s)
        self.yaw = Series(keep_s)  # (deg/s,) from a rate-of-turn sensor (ROT)
        self.throttle = Series(keep_s)  # (percent,)

    def add_position(
        self,
        t: float,
        lat: float | None,
        lon: float | None,
        v_east: float | None,
        v_north: float | None,
    ) -> None:
        self.position.add(t, (lat, lon, v_east, v_north))

    def add_position_sog_cog(
        self, t: float, lat: float | None, lon: float | None, sog: float | None, cog: float | None
    ) -> None:
        if sog is not None and cog is not None:
            ve, vn = velocity(sog, cog)
        elif sog is not None and sog == 0.0:
            ve = vn = 0.0
        else:
            ve = vn = None
        self.add_position(t, lat, lon, ve, vn)

    def add_heading(self, t: float, heading: float, yaw_rate: float | None = None) -> None:
        if yaw_rate is None:
            yaw_rate = self._slope(t, heading)
        self.heading.add(t, (wrap360(heading), yaw_rate))

    def _slope(self, t: float, heading: float) -> float | None:
        """Least-squares slope (deg/s) of the heading over the last ``YAW_WINDOW_S``, ``t`` included."""
        ts, vs = self.heading.t, self.heading.v
        pts = [(t, heading)]
        i = len(ts) - 1
        while i >= 0 and 0 <= t - ts[i] <= YAW_WINDOW_S and pts[-1][0] - ts[i] <= self.max_gap_s:
            prev_h = pts[-1][1]
            pts.append((ts[i], prev_h + wrap_to_180(vs[i][0] - prev_h)))
            i -= 1
        if len(pts) < 2:
            return None
        n = len(pts)
        mt = sum(p[0] for p in pts) / n
        mh = sum(p[1] for p in pts) / n
        stt = sum((p[0] - mt) ** 2 for p in pts)
        if stt <= 0:
            return None
        return sum((p[0] - mt) * (p[1] - mh) for p in pts) / stt

    def source_interval(self, series: str, interval_s: float) -> None:
        """The chosen source of ``series`` speaks every ``interval_s``: bridge its own gaps."""
        self.gaps[series] = max(self.max_gap_s, 1.6 * interval_s)

    def add_yaw_rate(self, t: float, rate: float) -> None:
        """A rate-of-turn reading (deg/s): it replaces the heading's derivative where it covers."""
        self.yaw.add(t, (rate,))

    def add_throttle(self, t: float, throttle: float) -> None:
        self.throttle.add(t, (throttle,))

    def covered_until(self) -> float | None:
        """The latest time up to which the navigation streams are known (the older of the two)."""
        a, b = self.position.last_t, self.heading.last_t
        if a is None and b is None:
            return None
        if a is None or b is None:
            return a if b is None else b
        return min(a, b)

    def reset(self) -> None:
        self.position.clear()
        self.heading.clear()
        self.yaw.clear()
        self.throttle.clear()

    def at(self, t: float, edge: bool = False) -> FusedBoatState:
        """The state at ``t``; fields stay None where the streams don't cover ``t``.

        ``edge``: where interpolation has no sample on one side (the end of a log, or an instrument
        that is read as it arrives), take the nearest sample within ``max_gap_s`` instead.
        """
        interp = self.sync == "interpolate"
        st = FusedBoatState(t)
        vals = []
        for name, series in (
            ("position", self.position),
            ("heading", self.heading),
            ("throttle", self.throttle),
        ):
            gap = self.gaps[name]
            if interp:
                v = series.interpolate(t, gap)
                if v is None and edge:
                    v = series.nearest(t, gap)
            else:
                v = series.nearest(t, gap / 2)
            vals.append(v)
        p, h, th = vals
        if p is not None:
            st.lat, st.lon, st.v_east, st.v_north = p
        if h is not None:
            st.heading, st.yaw_rate = h
        if th is not None:
            st.throttle = th[0]
        if self.yaw.t:
            y = self.yaw.interpolate(t, self.max_gap_s) if interp else None
            if y is None:
                y = self.yaw.nearest(
                    t, self.max_gap_s if edge or not interp else self.max_gap_s / 2
                )
            if y is not None:
                st.yaw_rate = y[0]
        return st
