"""Navigation estimated from every source of a log: position, velocity, heading and rate of turn.

``Navigation.fit`` takes every reading of a log (forcemap.host.convert.nav_readings) and:

1. smooths the position and ground velocity of every receiver (each on its own UTC stamps, with its
   own noise and bias; RMC's SOG and COG, and VTG, as velocity readings) with the robust RTS
   smoother (forcemap.host.fuse.smoother) in the local tangent plane;
2. estimates every compass's and rate-of-turn sensor's latency against the smoothed course and
   each other (forcemap.host.fuse.latency), and the speed log's against the speed over ground
   (forcemap.host.fuse.source_stats.latency);
3. smooths the heading and yaw rate from every compass and rate-of-turn sensor, each shifted by its
   latency (``remove_latency``), with its own noise and bias against the reference compass.

``state(t)`` gives the smoothed state at any instants (the samples rows' own times), and ``fits_``
each source's latency, noise, bias and outlier count (docs/NAVIGATION.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.convert.nav_readings import SourceData
from forcemap.host.fuse import source_stats
from forcemap.host.fuse.latency import heading_latencies
from forcemap.host.fuse.smoother import Channel, CvSmoother
from forcemap.host.vessel.geodesy import LocalFrame

Q_POSITION = 0.5  # m^2/s^3 without ground velocity readings (turning at 3 m/s: 0.5 m/s^2)
Q_HEADING = 50.0  # deg^2/s^3
POSITION_GAP_S = 12.0  # a row further than this from any position reading keeps its own
HEADING_GAP_S = 5.0
# a fix's stated noise (m, per axis, at HDOP 1) by its class (fix_quality.FIX_NAMES): the usual
# user-equivalent range errors of each kind of fix; the data decide where a receiver states nothing
UERE_M = {1: 10.0, 2: 4.0, 3: 2.0, 4: 0.5, 5: 0.2, 6: 0.02}
JUMP_M = 200.0
# the acceleration's density from the ground-velocity readings (acceleration_density): from a
# sailing boat on a steady reach (0.001) to a jet boat's turns (about 0.5)
Q_RANGE = (1e-3, 2.0)  # m^2/s^3
MIN_Q_READINGS = 30
MAX_Q_GAP_S = 10.0
MIN_DT_S = 0.05
G = 9.81  # m/s^2
SINGER = 4.0  # Singer's white density over the velocity increments' measure, at T = tau
SAME_FIX_S = 0.5  # one receiver's RMC, GGA and GLL of one fix are stamped 0.2-0.4 s apart
VELOCITY_FLOOR = 0.03  # m/s: no SOG is better than this, whatever its decimals say
MIN_VELOCITY_LAG_S = 0.5  # a smaller lag of a ground velocity is not told from its noise
MIN_VELOCITY_R = 0.7  # a velocity source's lag is taken from a clear correlation peak only
GRID = source_stats.GRID_S
# the speed log against the speed over ground: their accelerations differ by the current's change
# along the track, so a lag is taken only from a clear correlation peak
MIN_STW_R = 0.5  # a position this far from its neighbours' median is an outlier from the start


@dataclass
class SourceFit:
    """What the smoother learnt about one source."""

    quantity: str  # position, velocity, heading, yaw_rate, stw
    source: str
    readings: int
    noise: float = math.nan
    bias: float = math.nan
    unit: str = ""
    outliers: int = 0
    latency: float | None = None
    latency_sd: float | None = None
    latency_note: str = ""
    pairs: list[tuple[str, float]] = field(default_factory=list)  # (against, lag s)
    applied: bool = False  # the latency was removed


def stated_noise(s: SourceData) -> float | None:
    """The noise (m, per axis) a receiver's sentences state: its usual fix class and median HDOP
    (UERE_M), never below its minutes' quantisation (a step over the square root of 12)."""
    if not s.fixes:
        return None
    classes = np.bincount(np.asarray(s.fixes, int))
    uere = UERE_M.get(int(np.argmax(classes)))
    if uere is None:
        return None
    hdop = float(np.median(s.hdops)) if s.hdops else 1.0
    step = 1852.0 * 10.0**-s.decimals if s.decimals else 0.0
    return max(uere * max(hdop, 0.5), step / math.sqrt(12.0))


def acceleration_density(channels: list[Channel]) -> float | None:
    """The white acceleration's spectral density (m^2/s^3, per axis) the log's own ground-velocity
    readings show, or None without them. Over an interval ``tau`` a boat's velocity changes by
    ``a tau`` (a turn's acceleration is smooth: Singer's model, variance ``s2`` correlated over
    ``T``), so ``|dv|^2 / (2 tau)`` per axis measures ``s2 tau / 2``, and the white density that
    model equals is ``2 s2 T``: ``SINGER`` (4) times the measure with ``T = tau``, ``tau`` the
    longest interval the track has to bridge (the slowest receiver's between fixes). The mean over
    each source's readings ``tau`` apart (manoeuvres included: q is the acceleration's mean power);
    a reading's own noise only adds to it, so each source's figure is an upper bound and the least
    is kept. Increments beyond 1 g (no boat turns or brakes harder: a garbled reading) and across
    silences longer than MAX_Q_GAP_S do not count. Bounded to Q_RANGE."""
    tau = float(np.clip(max(map(_fix_interval, channels), default=1.0), MIN_DT_S, MAX_Q_GAP_S / 2))
    found = []
    for c in channels:
        if c.kind != "rate" or c.n < MIN_Q_READINGS:
            continue
        i = np.arange(c.n)
        j = np.searchsorted(c.t, c.t + tau - MIN_DT_S)
        i, j = i[j < c.n], j[j < c.n]
        dt = c.t[j] - c.t[i]
        a2 = ((c.z[j, :2] - c.z[i, :2]) ** 2).sum(axis=1)
        ok = (dt <= MAX_Q_GAP_S) & (a2 <= (G * dt) ** 2)
        if ok.sum() >= MIN_Q_READINGS:
            found.append(SINGER * float(np.mean(a2[ok] / (2 * dt[ok]))))
    if not found:
        return None
    return float(np.clip(min(found), *Q_RANGE))


def _fix_interval(c: Channel) -> float:
    """The median interval between a receiver's fixes (its sentences of one fix, stamped within
    SAME_FIX_S of each other, are one); 0 for a velocity source."""
    if c.kind != "value" or c.n < 3:
        return 0.0
    dt = np.diff(c.t)
    apart = dt[dt > SAME_FIX_S]
    return float(np.median(apart if len(apart) else dt))


def _screen(xy: np.ndarray) -> np.ndarray:
    """Positions far from the running median of their neighbours (jumps): weight 0 from the start."""
    n = len(xy)
    bad = np.zeros(n, bool)
    med = np.median(xy, axis=0)
    far = np.hypot(*(xy - med).T)
    bad |= far > max(50_000.0, 20 * float(np.median(far)))
    k = min(31, n if n % 2 else n - 1)
    if k >= 5:
        from numpy.lib.stride_tricks import sliding_window_view

        pad = np.pad(xy, ((k // 2, k // 2), (0, 0)), mode="edge")
        mx = np.median(sliding_window_view(pad[:, 0], k), axis=1)
        my = np.median(sliding_window_view(pad[:, 1], k), axis=1)
        bad |= np.hypot(xy[:, 0] - mx, xy[:, 1] - my) > JUMP_M
    return bad


def _velocity(sog: np.ndarray, cog: np.ndarray) -> np.ndarray:
    """(n, 2) east and north of speeds and courses (compass degrees)."""
    c = np.radians(cog)
    return np.column_stack([sog * np.sin(c), sog * np.cos(c)])


def _near(t_read: np.ndarray, t: np.ndarray, gap: float) -> np.ndarray:
    """Whether each of ``t`` has a reading within ``gap``."""
    if not len(t_read):
        return np.zeros(len(t), bool)
    s = np.sort(t_read)
    i = np.clip(np.searchsorted(s, t), 1, len(s) - 1) if len(s) > 1 else np.zeros(len(t), int)
    d = np.minimum(np.abs(s[i] - t), np.abs(s[np.maximum(i - 1, 0)] - t))
    return d <= gap


class Navigation:
    """Smoothed navigation of one log (scikit-learn conventions: ``fit`` returns self)."""

    def __init__(
        self,
        remove_latency: bool = True,
        q_position: float | None = None,
        q_heading: float = Q_HEADING,
    ) -> None:
        self.remove_latency = remove_latency
        self.q_position = q_position
        self.q_heading = q_heading

    def fit(self, readings: dict[str, dict[str, SourceData]], query: np.ndarray) -> Navigation:
        query = np.asarray(query, float)
        self.fits_: list[SourceFit] = []
        self.frame_: LocalFrame | None = None
        self.pos_: CvSmoother | None = None
        self.hdg_: CvSmoother | None = None
        self.pos_t_ = np.zeros(0)
        self.hdg_t_ = np.zeros(0)
        self.stw_latency_: float | None = None
        self._position(readings, query)
        self._heading(readings, query)
        self._speed_log(readings)
        return self

    # --- position ---------------------------------------------------------------------------------

    def _position(self, readings: dict[str, dict[str, SourceData]], query: np.ndarray) -> None:
        sources = readings.get("position", {})
        arrays = {n: s.arrays() for n, s in sources.items()}
        arrays = {n: (t, v) for n, (t, v) in arrays.items() if len(t) and v.shape[1] >= 2}
        ok_all = [v[np.isfinite(v[:, 0]) & np.isfinite(v[:, 1])] for _, v in arrays.values()]
        if not ok_all or not sum(len(v) for v in ok_all):
            return
        both = np.concatenate(ok_all)
        frame = self.frame_ = LocalFrame(float(np.median(both[:, 0])), float(np.median(both[:, 1])))
        channels: list[Channel] = []
        times = []
        for name, (t, v) in arrays.items():
            ok = np.isfinite(v[:, 0]) & np.isfinite(v[:, 1])
            x, y = frame.to_local(v[ok, 0], v[ok, 1])
            xy = np.column_stack([x, y])
            c = Channel(name, "value", t[ok], xy, sigma0=3.0, floor=0.05)
            c.prior_sigma = stated_noise(sources[name])
            c.weights_ = np.where(_screen(xy), 0.0, 1.0) if len(xy) else np.ones(0)
            channels.append(c)
            times.append(c.t[c.weights_ > 0])
            if v.shape[1] >= 4:
                okv = ok & np.isfinite(v[:, 2]) & np.isfinite(v[:, 3])
                if okv.sum() > 2:
                    vel = _velocity(v[okv, 2], v[okv, 3])
                    channels.append(
                        Channel(name, "rate", t[okv], vel, sigma0=0.3, floor=VELOCITY_FLOOR)
                    )
        for name, s in readings.get("velocity", {}).items():
            t, v = s.arrays()
            okv = np.isfinite(v[:, 0]) & np.isfinite(v[:, 1]) if v.shape[1] >= 2 else []
            if len(t) and np.sum(okv) > 2:
                vel = _velocity(v[okv, 0], v[okv, 1])
                channels.append(
                    Channel(name, "rate", t[okv], vel, sigma0=0.3, floor=VELOCITY_FLOOR)
                )
        lags = self._velocity_latencies(channels)
        q = acceleration_density(channels) if self.q_position is None else self.q_position
        self.q_position_ = Q_POSITION if q is None else q
        self.pos_ = CvSmoother(self.q_position_).fit(channels, query)
        self.pos_t_ = np.concatenate(times) if times else np.zeros(0)
        for c in channels:
            q = "position" if c.kind == "value" else "velocity"
            fit = SourceFit(q, c.source, c.n, c.sigma_, float(np.hypot(*c.bias_[:2])), "m")
            if q == "velocity":
                fit.unit, fit.bias = "m/s", math.nan
            fit.outliers, fit.latency = c.outliers_, 0.0
            fit.latency_note = "the time reference" if q == "position" else ""
            if q == "velocity":
                fit.latency, fit.latency_note = lags.get(id(c), (None, ""))
                fit.applied = fit.latency is not None and c.latency == fit.latency != 0.0
                fit.pairs = [("position", fit.latency)] if fit.latency is not None else []
            self.fits_.append(fit)

    def _velocity_latencies(self, channels: list[Channel]) -> dict[int, tuple[float | None, str]]:
        """Each ground-velocity source's lag behind the positions (the velocity vector against the
        positions' change, source_stats.best_lag); removed where clear (a filtered or relayed SOG)."""
        values = [c for c in channels if c.kind == "value" and c.n > 10]
        if not values:
            return {}
        ref_c = max(values, key=lambda c: c.n)
        ok = ref_c.weights_ > 0
        pos = source_stats.Track("p", ref_c.t[ok], ref_c.z[ok])
        out: dict[int, tuple[float | None, str]] = {}
        for c in channels:
            if c.kind != "rate" or c.n < 10:
                continue
            vel = source_stats.Track("v", c.t, c.z)
            grid = source_stats._grid(pos, vel)
            if not len(grid):
                continue
            ref = np.stack(
                [
                    np.gradient(source_stats._on_grid(pos.t, pos.v[:, j], grid), GRID)
                    for j in (0, 1)
                ],
                axis=1,
            )
            sig = np.stack(
                [source_stats._on_grid(vel.t, vel.v[:, j], grid) for j in (0, 1)], axis=1
            )
            lag, peak = source_stats.best_lag(ref, sig, 15.0)
            if lag is None or peak is None or peak < MIN_VELOCITY_R:
                r = "" if peak is None else f" (r = {peak:.2f})"
                out[id(c)] = (None, f"no clear lag against the positions{r}")
                continue
            small = abs(lag) < MIN_VELOCITY_LAG_S
            out[id(c)] = (float(lag), "within the estimate's noise: not removed" if small else "")
            if self.remove_latency and not small:
                c.latency = float(lag)
        return out

    # --- heading ----------------------------------------------------------------------------------

    def _velocity_track(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        if self.pos_ is None or len(self.pos_t_) < 3:
            return None
        t = np.arange(self.pos_t_.min(), self.pos_t_.max(), 1.0)
        _, v = self.pos_.at(t)
        return t, v[:, 0], v[:, 1]

    def _heading(self, readings: dict[str, dict[str, SourceData]], query: np.ndarray) -> None:
        heads = {n: s.arrays() for n, s in readings.get("heading", {}).items()}
        rates = {n: s.arrays() for n, s in readings.get("yaw_rate", {}).items()}
        heads = {n: (t, v) for n, (t, v) in heads.items() if np.isfinite(v[:, 0]).sum() > 2}
        rates = {n: (t, v) for n, (t, v) in rates.items() if np.isfinite(v[:, 0]).sum() > 2}
        if not heads:
            return
        tr_h = {n: source_stats.Track(n, t, v[:, :1]) for n, (t, v) in heads.items()}
        tr_r = {n: source_stats.Track(n, t, v[:, :1]) for n, (t, v) in rates.items()}
        lat = heading_latencies(tr_h, tr_r, self._velocity_track())
        channels = []
        for kind, group in (("value", heads), ("rate", rates)):
            for n, (t, v) in group.items():
                ok = np.isfinite(v[:, 0])
                c = Channel(n, kind, t[ok], v[ok, :1], sigma0=2.0, floor=0.1)
                if kind == "rate":
                    c.bias_free, c.sigma0, c.floor = False, 1.0, 0.05
                got = lat.get(n)
                if self.remove_latency and got is not None and got.value is not None:
                    c.latency = got.value
                channels.append(c)
        # the first estimate, to unwrap every compass against: the most frequent one, unwrapped
        best = max(heads, key=lambda n: len(heads[n][0]))
        tb, vb = heads[best][0], heads[best][1][:, 0]
        okb = np.isfinite(vb)
        tb, hb = tb[okb], np.degrees(np.unwrap(np.radians(vb[okb])))
        lb = lat.get(best)
        shift = lb.value if self.remove_latency and lb and lb.value is not None else 0.0

        def init(t: np.ndarray) -> np.ndarray:
            return np.interp(t, tb - shift, hb)[:, None]

        self.hdg_ = CvSmoother(self.q_heading, wrap=360.0).fit(channels, query, init=init)
        self.hdg_t_ = np.concatenate([c.t - c.latency for c in channels if c.kind == "value"])
        for c in channels:
            q = "heading" if c.kind == "value" else "yaw_rate"
            unit = "deg" if q == "heading" else "deg/s"
            fit = SourceFit(q, c.source, c.n, c.sigma_, float(c.bias_[0]), unit, c.outliers_)
            got = lat.get(c.source)
            if got is not None:
                fit.latency, fit.latency_sd, fit.pairs = got.value, got.sd, got.pairs
                fit.latency_note = got.note
                fit.applied = self.remove_latency and got.value is not None
            self.fits_.append(fit)

    # --- speed through water ------------------------------------------------------------------------

    def _speed_log(self, readings: dict[str, dict[str, SourceData]]) -> None:
        vt = self._velocity_track()
        for name, s in readings.get("stw", {}).items():
            t, v = s.arrays()
            fit = SourceFit("stw", name, len(t), unit="m/s")
            if vt is not None and len(t) > 2 and self.frame_ is not None:
                tv = vt[0]
                p, _ = self.pos_.at(tv)  # type: ignore[union-attr]
                lat, lon = self.frame_.to_latlon(p[:, 0], p[:, 1])
                pos = source_stats.Track("smoothed", tv, np.column_stack([lat, lon]))
                value, peak = source_stats.latency("stw", source_stats.Track(name, t, v), pos)
                if value is not None and peak is not None and peak >= MIN_STW_R and abs(value) < 15:
                    fit.latency = float(value)
                    fit.applied = self.remove_latency
                    fit.pairs = [("speed over ground", float(value))]
                else:
                    r = "" if peak is None else f" (r = {peak:.2f} < {MIN_STW_R:g})"
                    fit.latency_note = f"no clear lag against the speed over ground{r}"
            if s.used and (self.stw_latency_ is None) and fit.latency is not None:
                self.stw_latency_ = fit.latency
            self.fits_.append(fit)

    # --- the answer ---------------------------------------------------------------------------------

    def state(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """lat, lon, v_east, v_north, heading, yaw_rate at ``t`` (NaN where no reading is near)."""
        t = np.asarray(t, float)
        nan = np.full(len(t), np.nan)
        out = {k: nan.copy() for k in ("lat", "lon", "v_east", "v_north", "heading", "yaw_rate")}
        if self.pos_ is not None and self.frame_ is not None:
            p, v = self.pos_.at(t)
            ok = _near(self.pos_t_, t, POSITION_GAP_S)
            lat, lon = self.frame_.to_latlon(p[:, 0], p[:, 1])
            out["lat"][ok], out["lon"][ok] = np.asarray(lat)[ok], np.asarray(lon)[ok]
            out["v_east"][ok], out["v_north"][ok] = v[ok, 0], v[ok, 1]
        if self.hdg_ is not None:
            h, r = self.hdg_.at(t)
            ok = _near(self.hdg_t_, t, HEADING_GAP_S)
            out["heading"][ok] = h[ok, 0] % 360.0
            out["yaw_rate"][ok] = r[ok, 0]
        return out
