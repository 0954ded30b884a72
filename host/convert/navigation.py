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
from forcemap.host.fuse import nav_model, source_stats
from forcemap.host.fuse.latency import heading_latencies
from forcemap.host.fuse.smoother import Channel, CvSmoother
from forcemap.host.vessel.geodesy import LocalFrame

JUMP_M = nav_model.JUMP_M
Q_POSITION, Q_HEADING = nav_model.Q_POSITION, nav_model.Q_HEADING
POSITION_GAP_S, HEADING_GAP_S = nav_model.POSITION_GAP_S, nav_model.HEADING_GAP_S
VELOCITY_FLOOR = nav_model.VELOCITY_FLOOR
GRID = source_stats.GRID_S
# the speed log against the speed over ground: their accelerations differ by the current's change
# along the track, so a lag is taken only from a clear correlation peak
MIN_STW_R = 0.5


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
    (nav_model.fix_noise)."""
    if not s.fixes:
        return None
    fix_class = int(np.argmax(np.bincount(np.asarray(s.fixes, int))))
    hdop = float(np.median(s.hdops)) if s.hdops else None
    return nav_model.fix_noise(fix_class, hdop, s.decimals)


_screen, _velocity, _near = nav_model.screen, nav_model.velocity, nav_model.near


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
            vel = _velocity(v[ok, 2], v[ok, 3]) if v.shape[1] >= 4 else None
            got = nav_model.position_channels(name, t[ok], xy, vel, stated_noise(sources[name]))
            channels.extend(got)
            times.append(got[0].t[got[0].weights_ > 0])
        for name, s in readings.get("velocity", {}).items():
            t, v = s.arrays()
            okv = np.isfinite(v[:, 0]) & np.isfinite(v[:, 1]) if v.shape[1] >= 2 else []
            if len(t) and np.sum(okv) > 2:
                channels.append(
                    nav_model.velocity_channel(name, t[okv], _velocity(v[okv, 0], v[okv, 1]))
                )
        lags = self._velocity_latencies(channels)
        q = nav_model.acceleration_density(channels) if self.q_position is None else self.q_position
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
        """Each ground-velocity source's lag behind the positions (nav_model.velocity_latencies);
        removed where clear (a filtered or relayed SOG)."""
        out = nav_model.velocity_latencies(channels)
        for c in channels:
            lag, note = out.get(id(c), (None, ""))
            if self.remove_latency and lag is not None and not note:
                c.latency = lag
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
                got = lat.get(n)
                shift = got.value if self.remove_latency and got and got.value is not None else 0.0
                channels.append(nav_model.heading_channel(n, kind, t[ok], v[ok, :1], shift))
        # the first estimate, to unwrap every compass against: the most frequent one, unwrapped
        best = max(heads, key=lambda n: len(heads[n][0]))
        tb, hb = nav_model.unwrapped(heads[best][0], heads[best][1][:, 0])
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
