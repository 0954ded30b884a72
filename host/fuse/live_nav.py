"""The daemon's navigation: a fixed-lag smoother over a sliding window of every source's readings.

``forcemap run`` makes each samples row from the same models as the log smoother
(forcemap.host.fuse.nav_model, forcemap.host.fuse.smoother): every receiver (its RMC, GGA and GLL
one source, each fix at its own UTC stamp), every ground velocity, compass and rate-of-turn sensor,
each with its own noise, bias and Huber weights, the heading wrapped. It stays causal: a row at
``t`` waits ``lag_s`` (its stated lag; at most SOLVE_PERIOD_S more: one solve serves every row
ready in that time), then the readings of the last ``window_s`` before it up to
the present are solved and the state is read at ``t``. A slow receiver's next fix within the lag
is interpolated towards; beyond it, the model's own velocity carries the track. The compasses' and
rate-of-turn sensors' latencies (forcemap.host.fuse.latency), and each ground velocity's lag behind
the positions, are measured every ``LATENCY_PERIOD_S`` over the last ``LATENCY_WINDOW_S`` and removed
as the log smoother does.

An autopilot's navigation (MAVLink, DataFlash) is its EKF's: once its position is used, the filter
stands aside and the rows keep it. Bad readings are counted (``rejected``), never raised.
"""

from __future__ import annotations

import math
import re
from collections import Counter, deque
from collections.abc import Callable

import numpy as np
from forcemap.host.fuse import nav_model as nm
from forcemap.host.fuse.latency import heading_latencies
from forcemap.host.fuse.smoother import Channel, CvSmoother
from forcemap.host.fuse.source_stats import Track
from forcemap.host.fuse.sources import AUTOPILOT_CONNECTIONS, split_name
from forcemap.host.fuse.state import FusedBoatState
from forcemap.host.vessel.geodesy import LocalFrame

LAG_S = 3.0  # s: how long a row waits for the readings after it (the boat file's live_lag_s)
WINDOW_S = 60.0  # s of readings before a row that are solved with it
LATENCY_WINDOW_S = 600.0  # s of readings the latencies are measured on ...
LATENCY_PERIOD_S = 60.0  # ... every this often
MIN_LATENCY_SPAN_S = 120.0  # no latency is measured on less
SOLVE_PERIOD_S = 1.0  # at most one solve this often, whatever the rows' rate
FRAME_KM = 10.0
MOVED_DEG = 1.5e-5  # one stamp on positions this far apart is not one fix (nav_readings)
QUANTITIES = ("position", "velocity", "heading", "yaw_rate")
_DP = re.compile(r"(\d+)dp")


def _far(frame: LocalFrame, lat: float, lon: float) -> bool:
    """Whether a fix is so far from the frame's origin that the tangent plane bends (10 km)."""
    x, y = frame.to_local(np.array([lat]), np.array([lon]))
    return bool(math.hypot(float(x[0]), float(y[0])) > FRAME_KM * 1000.0)


class _Source:
    """One source's recent readings: (time, arrival, values) in arrival order."""

    __slots__ = ("rows", "same_stamp")

    def __init__(self) -> None:
        self.rows: deque[tuple[float, float, tuple[float, ...]]] = deque()
        self.same_stamp = 0  # fixes whose stamp repeats the last one's for a moved position

    def coarse(self) -> bool:
        return self.same_stamp > 0.1 * len(self.rows) and len(self.rows) >= 3

    def arrays(self, t0: float) -> tuple[np.ndarray, np.ndarray]:
        """Times (its stamps, or its arrival times when they are coarser than its fixes) from
        ``t0`` on, sorted, and the values (n, k)."""
        rows = []
        for r in reversed(self.rows):  # newest first: the window is the deque's tail
            if r[1] < t0:
                break
            rows.append(r)
        rows.reverse()
        if not rows:
            return np.zeros(0), np.zeros((0, 1))
        col = 1 if self.coarse() else 0
        t = np.array([r[col] for r in rows])
        v = np.array([r[2] for r in rows], float)
        order = np.argsort(t, kind="stable")
        return t[order], v[order]


class LiveNavigation:
    """Every navigation reading in (``add``), the smoothed state at rows' times out (``states``)."""

    def __init__(
        self,
        lag_s: float = LAG_S,
        window_s: float = WINDOW_S,
        remove_latency: bool = True,
        quality: Callable[[str], tuple[int | None, float | None]] | None = None,
    ) -> None:
        self.lag_s = lag_s
        self.window_s = window_s
        self.remove_latency = remove_latency
        self.quality = quality  # a receiver's current (fix class, HDOP): SourceSelector.quality
        self.sources: dict[str, dict[str, _Source]] = {q: {} for q in QUANTITIES}
        self.autopilot = False
        self.frame: LocalFrame | None = None
        self.latencies: dict[str, float] = {}  # compasses and rate-of-turn sensors
        self.velocity_lags: dict[str, float] = {}  # ground velocities behind the positions
        self._latency_t: float | None = None
        self.latest, self.first = -math.inf, math.inf
        self._solved = -math.inf
        self.counts: Counter[str] = Counter()

    @property
    def active(self) -> bool:
        """Whether the filter makes the rows: a receiver's positions, and no autopilot's."""
        return not self.autopilot and bool(self.sources["position"])

    # --- input ------------------------------------------------------------------------------------

    def add(
        self,
        quantity: str,
        source: str,
        t: float,
        value: tuple,
        used: bool,
        group: str | None = None,
        t_fix: float | None = None,
    ) -> None:
        """A reading of ``source`` arriving at ``t`` (``t_fix``: the instant its own UTC stamp
        names, on the same timeline); ``group``: the receiver of a position."""
        if quantity not in self.sources:
            return
        if split_name(source)[0] in AUTOPILOT_CONNECTIONS:
            self.autopilot |= used and quantity == "position"
            return
        width = 2 if quantity in ("position", "velocity") else 1
        vals = tuple(np.nan if x is None else float(x) for x in (value or ())[:width])
        if len(vals) < width or not all(math.isfinite(x) for x in vals) or not math.isfinite(t):
            self.counts[f"rejected_{quantity}"] += 1
            return
        if quantity == "position" and len(value) >= 4:
            vals += tuple(np.nan if x is None else float(x) for x in value[2:4])
        key = (group or source) if quantity == "position" else source
        src = self.sources[quantity].setdefault(key, _Source())
        stamp = t_fix if t_fix is not None and math.isfinite(t_fix) else t
        if quantity == "position":
            if self.frame is None or _far(self.frame, vals[0], vals[1]):
                self.frame = LocalFrame(vals[0], vals[1])  # each solve is in one frame
            if src.rows and src.rows[-1][0] == stamp:
                moved = max(abs(vals[0] - src.rows[-1][2][0]), abs(vals[1] - src.rows[-1][2][1]))
                src.same_stamp += moved > MOVED_DEG
        src.rows.append((stamp, t, vals))
        self.latest = max(self.latest, t)
        self.first = min(self.first, t)
        self.counts[quantity] += 1
        self._prune(src)

    def _prune(self, src: _Source) -> None:
        keep = self.latest - LATENCY_WINDOW_S
        while src.rows and src.rows[0][1] < keep:
            src.rows.popleft()

    def ready(self, t: float, now: float) -> bool:
        """Whether a row at ``t`` has waited its lag."""
        return now - t >= self.lag_s

    def due(self, t: float, now: float) -> bool:
        """Whether the rows up to ``t`` are solved now: ``t`` has waited its lag, and the last solve
        is SOLVE_PERIOD_S old (a row waits from ``lag_s`` to ``lag_s`` + SOLVE_PERIOD_S)."""
        return self.ready(t, now) and now - self._solved >= SOLVE_PERIOD_S

    # --- output -----------------------------------------------------------------------------------

    def states(self, times: list[float]) -> list[FusedBoatState] | None:
        """The state at each of ``times`` from the readings of the window before the earliest up
        to the latest one; None when the filter stands aside or cannot solve (counted)."""
        if not self.active or not times:
            return None
        self._solved = self.latest
        try:
            return self._states(np.asarray(times, float))
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            self.counts["unsolved"] += 1
            return None

    def _states(self, t: np.ndarray) -> list[FusedBoatState]:
        if self.remove_latency and (
            self._latency_t is None or self.latest - self._latency_t >= LATENCY_PERIOD_S
        ):
            self._measure_latencies()
        t0 = float(t.min()) - self.window_s
        out = [FusedBoatState(float(ti)) for ti in t]
        pos = self._position(t0, t)
        if pos is not None:
            fit, seen = pos
            p, v = fit.at(t)
            ok = nm.near(seen, t, nm.POSITION_GAP_S)
            lat, lon = self.frame.to_latlon(p[:, 0], p[:, 1])  # type: ignore[union-attr]
            for i in np.flatnonzero(ok):
                s = out[i]
                s.lat, s.lon = float(lat[i]), float(lon[i])
                s.v_east, s.v_north = float(v[i, 0]), float(v[i, 1])
        hdg = self._heading(t0, t)
        if hdg is not None:
            fit, seen = hdg
            h, r = fit.at(t)
            ok = nm.near(seen, t, nm.HEADING_GAP_S)
            for i in np.flatnonzero(ok):
                out[i].heading, out[i].yaw_rate = float(h[i, 0] % 360.0), float(r[i, 0])
        self.counts["solves"] += 1
        return out

    def _position_channels(self, t0: float) -> list[Channel]:
        frame = self.frame
        channels: list[Channel] = []
        if frame is None:
            return channels
        for name, src in self.sources["position"].items():
            t, v = src.arrays(t0)
            if not len(t):
                continue
            x, y = frame.to_local(v[:, 0], v[:, 1])
            vel = nm.velocity(v[:, 2], v[:, 3]) if v.shape[1] >= 4 else None
            channels += nm.position_channels(
                name, t, np.column_stack([x, y]), vel, self._noise(name)
            )
        for name, src in self.sources["velocity"].items():
            t, v = src.arrays(t0)
            if len(t) > 2:
                channels.append(nm.velocity_channel(name, t, nm.velocity(v[:, 0], v[:, 1])))
        if self.remove_latency:  # a ground velocity lagging the positions (velocity_latencies)
            for c in channels:
                if c.kind == "rate":
                    c.latency = self.velocity_lags.get(c.source, 0.0)
        return channels

    def _noise(self, receiver: str) -> float | None:
        """The noise a receiver's fix states now (nav_model.fix_noise)."""
        if self.quality is None:
            return None
        fix_class, hdop = self.quality(receiver)
        m = _DP.search(receiver)
        return nm.fix_noise(fix_class, hdop, int(m.group(1)) if m else 0)

    def _position(self, t0: float, query: np.ndarray) -> tuple[CvSmoother, np.ndarray] | None:
        channels = self._position_channels(t0)
        values = [c for c in channels if c.kind == "value"]
        if not values:
            return None
        q = nm.acceleration_density(channels)
        fit = CvSmoother(nm.Q_POSITION if q is None else q).fit(channels, query)
        return fit, np.concatenate([c.t[c.weights_ > 0] for c in values])

    def _heading_channels(self, t0: float, latency: bool) -> tuple[list[Channel], dict]:
        channels, heads = [], {}
        for quantity, kind in (("heading", "value"), ("yaw_rate", "rate")):
            for name, src in self.sources[quantity].items():
                t, v = src.arrays(t0)
                if len(t) <= 2:
                    continue
                shift = self.latencies.get(name, 0.0) if latency else 0.0
                channels.append(nm.heading_channel(name, kind, t, v[:, :1], shift))
                if kind == "value":
                    heads[name] = (t, v[:, 0], shift)
        return channels, heads

    def _heading(self, t0: float, query: np.ndarray) -> tuple[CvSmoother, np.ndarray] | None:
        channels, heads = self._heading_channels(t0, self.remove_latency)
        if not heads:
            return None
        tb, vb, shift = max(heads.values(), key=lambda h: len(h[0]))
        tb, hb = nm.unwrapped(tb, vb)

        def init(t: np.ndarray) -> np.ndarray:
            return np.interp(t, tb - shift, hb)[:, None]

        fit = CvSmoother(nm.Q_HEADING, wrap=360.0).fit(channels, query, init=init)
        return fit, np.concatenate([c.t - c.latency for c in channels if c.kind == "value"])

    def _measure_velocity_lags(self, t0: float) -> None:
        channels = self._position_channels(t0)
        got = nm.velocity_latencies(channels)
        self.velocity_lags = {
            c.source: lag
            for c in channels
            if c.kind == "rate"
            for lag, note in [got.get(id(c), (None, "x"))]
            if lag is not None and not note
        }

    def _measure_latencies(self) -> None:
        """Every compass's, rate-of-turn sensor's and ground velocity's latency over the last
        LATENCY_WINDOW_S, once there are MIN_LATENCY_SPAN_S of readings."""
        if self.latest - self.first < MIN_LATENCY_SPAN_S:
            return
        self._latency_t = self.latest
        t0 = self.latest - LATENCY_WINDOW_S
        self._measure_velocity_lags(t0)
        channels, heads = self._heading_channels(t0, latency=False)
        if not heads:
            return
        tr_h = {c.source: Track(c.source, c.t, c.z) for c in channels if c.kind == "value"}
        tr_r = {c.source: Track(c.source, c.t, c.z) for c in channels if c.kind == "rate"}
        velocity = None
        pos = self._position(t0, np.zeros(0))
        if pos is not None and len(pos[1]) > 2:
            tv = np.arange(float(pos[1].min()), float(pos[1].max()), 1.0)
            _, v = pos[0].at(tv)
            velocity = (tv, v[:, 0], v[:, 1])
        got = heading_latencies(tr_h, tr_r, velocity)
        self.latencies = {n: lat.value for n, lat in got.items() if lat.value is not None}
        self.counts["latency_measures"] += 1
