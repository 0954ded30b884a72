"""Samples from whatever the boat has: one table row whenever the boat state is known.

The decoders (decode_bridge, decode_nmea, decode_mavlink, dataflash) hand the assembler navigation
(into ``state``) and measurements (apparent wind, the instrument's true wind, speed through water,
depth, water temperature, paddle wheels). Rows come at a fixed rate:

- with the bridge, one row per bridge SAMPLE (4 Hz), at the frame's own time;
- otherwise, by default, one row per reading of the fastest measurement stream, at its own time, so
  that reading is used as measured; with ``rate_hz`` set, one row per tick of that fixed grid.

A row waits until the navigation streams have passed its time (at most ``hold_s``), so the boat
state is interpolated at the row's own time. Every other measurement column takes the reading
nearest in time within its ``MAX_AGE_S``, and stays empty (null) otherwise. The ``columns``
metadata record says which source and sentence or message fed each column.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

from forcemap.host.fuse import attitude
from forcemap.host.fuse import compensation as comp
from forcemap.host.fuse.state import Series, StateEstimator
from forcemap.host.log.messages import Current, Sample, SetAndDrift, TrueWind

if TYPE_CHECKING:
    from forcemap.host.fuse.calibration import Calibration
    from forcemap.host.fuse.live_nav import LiveNavigation

# how far a reading may be from the row's time and still fill it (s)
MAX_AGE_S = {"app": 2.0, "true": 2.0, "stw": 2.0, "depth": 5.0, "temp": 60.0, "attitude": 2.0}
# another stream paces the rows once it has this many times the readings of the current one
PACE_SWITCH = 1.25
GRID_MAX_CATCHUP = 20  # grid ticks made up at most after a silence


@dataclass(slots=True)
class Pending:
    """A row waiting for the navigation streams: bridge readings, or a bare tick."""

    t: float  # host wall seconds
    app_speed: float | None = None
    app_angle: float | None = None
    wheels: list[float] | None = None


class _Reading:
    """Recent readings of one quantity with the label of who gave them."""

    __slots__ = ("series", "label", "max_age")

    def __init__(self, max_age: float) -> None:
        self.series = Series(keep_s=120.0)
        self.label = ""
        self.max_age = max_age

    def add(self, t: float, value: tuple, label: str) -> None:
        self.series.add(t, value)
        self.label = label

    def at(self, t: float) -> tuple | None:
        return self.series.nearest(t, self.max_age)


class SampleAssembler:
    """Navigation and measurements in, ``/samples`` (and ``/current``, ``/current/stw``) out."""

    def __init__(
        self,
        cal: Calibration,
        out: Any,
        *,
        sync: str,
        rate_lag_s: float,
        hold_s: float,
        rate_hz: float | None = None,
    ) -> None:
        self.cal = cal
        self.out = out  # the pipeline: .write(topic, wall_s, record), .metadata(name, data)
        self.state = StateEstimator(sync, cal.max_state_gap_s)
        self.angles = [w.angle_deg for w in cal.wheels]
        self.rate_lag_s = rate_lag_s
        self.hold_s = hold_s
        self.rate_hz = rate_hz
        self.pending: deque[Pending] = deque()
        self.app = _Reading(MAX_AGE_S["app"])
        self.true = _Reading(MAX_AGE_S["true"])
        self.stw = _Reading(MAX_AGE_S["stw"])
        self.depth = _Reading(MAX_AGE_S["depth"])
        self.temp = _Reading(MAX_AGE_S["temp"])
        self.attitude = _Reading(MAX_AGE_S["attitude"])
        self.nav: dict[str, str] = {}  # position, velocity, heading, yaw_rate, throttle -> source
        self.bridge = False
        self.stream_counts: Counter[str] = Counter()
        self.pace: str | None = None
        self._next_tick: float | None = None
        self.columns: dict[str, set[str]] = {}
        self._fed_keys: set[tuple] = set()
        self.counts: Counter[str] = Counter()
        self.live: LiveNavigation | None = None  # the daemon's filter (forcemap run), if on

    # --- input ----------------------------------------------------------------------------------

    def bridge_sample(
        self, t: float, speed: float | None, angle: float | None, wheels: list
    ) -> None:
        """One bridge SAMPLE: apparent wind and paddle wheels; the bridge paces the rows."""
        self.bridge = True
        self.pending.append(Pending(t, speed, angle, wheels))

    def reading(self, kind: str, t: float, value: tuple, label: str) -> None:
        """A measurement: ``kind`` is app (speed, angle), true (speed, dir), stw (m/s,),
        depth (m,), temp (deg C,) or attitude (roll, pitch deg); ``label`` names the source and
        sentence."""
        if kind == "depth":  # its own time: the tilt correction takes the attitude of that moment
            value = (value[0], t)
        getattr(self, kind).add(t, value, label)
        if kind != "attitude":  # the hull's attitude describes a row, it never makes one
            self._pace(label, t)

    def _pace(self, stream: str, t: float) -> None:
        if self.bridge:
            return
        if self.rate_hz:
            self._grid(t)
            return
        n = self.stream_counts[stream] = self.stream_counts[stream] + 1
        if self.pace is None or n > PACE_SWITCH * self.stream_counts[self.pace] + 2:
            self.pace = stream
        if stream == self.pace:
            self.pending.append(Pending(t))

    def _grid(self, t: float) -> None:
        step = 1.0 / self.rate_hz  # type: ignore[operator]
        if self._next_tick is None or t - self._next_tick > GRID_MAX_CATCHUP * step:
            self._next_tick = math.ceil(t / step) * step
        while self._next_tick <= t:
            self.pending.append(Pending(self._next_tick))
            self._next_tick += step

    # --- output ---------------------------------------------------------------------------------

    def drain(self, now: float, final: bool) -> None:
        """Emit the rows the navigation has passed, those older than ``hold_s``, or all (final);
        with the live filter, those that have waited its lag."""
        pend = self.pending
        if not pend:
            return
        if self.live is not None and self.live.active:
            self._drain_live(now, final)
            return
        covered = self.state.covered_until()
        while pend:
            p = pend[0]
            ready = final or (covered is not None and covered >= p.t) or now - p.t > self.hold_s
            if not ready:
                break
            pend.popleft()
            self._emit(p, edge=final or covered is None or covered < p.t)

    def _drain_live(self, now: float, final: bool) -> None:
        """The rows that have waited the filter's lag, each with its state at its own time (and at
        half a rate window before, for the paddle wheels), from one solve."""
        live, pend = self.live, self.pending
        if not final and not live.due(pend[0].t, now):  # type: ignore[union-attr]
            return
        ready = []
        while pend and (final or live.ready(pend[0].t, now)):  # type: ignore[union-attr]
            ready.append(pend.popleft())
        if not ready:
            return
        times = [p.t for p in ready]
        if self.rate_lag_s:
            times += [p.t - self.rate_lag_s for p in ready if p.wheels is not None]
        got = live.states(times)  # type: ignore[union-attr]
        at = dict(zip(times, got, strict=True)) if got is not None else {}
        for p in ready:
            self._emit(p, edge=True, live=at)

    def _state(self, t: float, edge: bool, live: dict[float, Any] | None) -> Any:
        """The boat state at ``t``: the chosen sources', with the live filter's where it has one."""
        st = self.state.at(t, edge=edge)
        f = live.get(t) if live else None
        if f is not None:
            for field in fields(f):
                value = getattr(f, field.name)
                if value is not None and field.name != "t":
                    setattr(st, field.name, value)
        return st

    def _emit(self, p: Pending, edge: bool, live: dict[float, Any] | None = None) -> None:
        st = self._state(p.t, edge, live)
        moving = st.heading is not None and st.v_east is not None and st.v_north is not None
        if p.wheels is None and st.lat is None:
            self.counts["ticks_without_position"] += 1
            return  # a row needs a position; the bridge's rows keep their old rule
        if not moving:
            self.counts["samples_without_state"] += 1
        t_log = self.out.utc_s(p.t)
        row = Sample(t_log, st.lat, st.lon, st.heading, st.yaw_rate, st.sog, st.cog)
        row.throttle = st.throttle
        labels = self._measurements(row, p)
        if moving:
            self._true_wind(row, p, st, labels)
            self._stw_current(row, p.t, st, labels)
        if p.wheels is not None:
            self._wheels(row, p, st, edge, moving, live)
        self._provenance(row, labels)
        self.out.write("/samples", p.t, row)
        self.counts["samples"] += 1

    def _measurements(self, row: Sample, p: Pending) -> dict[str, str]:
        labels: dict[str, str] = {}
        if p.wheels is not None:
            row.app_wind_speed, row.app_wind_angle = p.app_speed, p.app_angle
            labels["app"] = "bridge anemometer+vane"
        else:
            a = self.app.at(p.t)
            if a is not None:
                row.app_wind_speed, row.app_wind_angle = a
                labels["app"] = self.app.label
        for name, col in (("depth", "depth"), ("temp", "water_temp"), ("stw", "stw")):
            reading = getattr(self, name)
            v = reading.at(p.t)
            if v is not None:
                setattr(row, col, v[0])
                labels[name] = reading.label
        w = self.true.at(p.t)
        if w is not None and w[1] is not None:
            row.wind_speed_instrument, row.wind_dir_instrument = w
            labels["true"] = self.true.label
        att = self.attitude.at(p.t)
        if att is not None:
            row.roll, row.pitch = att
            labels["attitude"] = self.attitude.label
        self._sounding(row, p.t)
        return labels

    def _sounding(self, row: Sample, t: float) -> None:
        """The depth corrected for the transducer's tilt where the beam angle is known, with the
        hull's attitude at the sounding's own time (the reading kept as ``depth_raw``), and the rows
        in a stretch where the bottom was lost marked."""
        cal = self.cal
        if row.depth is not None and row.roll is not None and cal.sounder_beam_deg is not None:
            sounding = self.depth.at(t)
            att = self.attitude.series.interpolate(sounding[1], MAX_AGE_S["attitude"])
            roll, pitch = att if att is not None and att[0] is not None else (row.roll, row.pitch)
            row.depth_raw = row.depth
            row.depth = float(
                attitude.corrected(row.depth, cal.depth_offset_m, roll, pitch, cal.sounder_beam_deg)
            )
        if cal.depth_lost:
            row.bottom_lost = float(any(a <= row.t <= b for a, b in cal.depth_lost))

    def _true_wind(self, row: Sample, p: Pending, st: Any, labels: dict[str, str]) -> None:
        if row.app_wind_speed is not None and row.app_wind_angle is not None:
            we, wn = comp.true_wind(
                row.app_wind_speed, row.app_wind_angle, st.heading, st.v_east, st.v_north
            )
            row.wind_east, row.wind_north = we, wn
            row.wind_speed, row.wind_dir = math.hypot(we, wn), comp.from_direction(we, wn)
            if p.wheels is not None:
                msg = TrueWind(row.t, row.wind_speed, row.wind_dir, we, wn, source="bridge")
                msg.app_speed, msg.app_angle = row.app_wind_speed, row.app_wind_angle
                msg.heading, msg.boat_east, msg.boat_north = st.heading, st.v_east, st.v_north
                self.out.write("/wind/true", p.t, msg)
        elif row.wind_speed_instrument is not None:
            row.wind_speed, row.wind_dir = row.wind_speed_instrument, row.wind_dir_instrument
            we, wn = comp.velocity(row.wind_speed, row.wind_dir)
            row.wind_east, row.wind_north = -we, -wn
            labels["wind_from_instrument"] = labels["true"]

    def _stw_current(self, row: Sample, t: float, st: Any, labels: dict[str, str]) -> None:
        if row.stw is None:
            return
        if any(a <= t <= b for a, b in self.cal.stw_dead):  # a dead log: the row stays, no STW
            row.stw = None
            return
        # a calibrated misalignment: the water passes the hull at heading + beta
        beta = self.cal.stw_misalignment_deg or 0.0
        ce, cn = comp.current_from_stw(row.stw, st.heading + beta, st.v_east, st.v_north)
        row.current_speed_stw, row.current_dir_stw = math.hypot(ce, cn), comp.to_direction(ce, cn)
        msg = SetAndDrift(
            row.t,
            row.current_speed_stw,
            row.current_dir_stw,
            ce,
            cn,
            row.stw,
            st.heading,
            st.v_east,
            st.v_north,
            labels["stw"],
        )
        self.out.write("/current/stw", t, msg)
        if not self.bridge:
            row.current_east, row.current_north = ce, cn
            row.current_speed, row.current_dir = row.current_speed_stw, row.current_dir_stw

    def _wheels(
        self, row: Sample, p: Pending, st: Any, edge: bool, moving: bool, live: dict | None
    ) -> None:
        cal = self.cal
        wheels = p.wheels or []
        for i, w in enumerate(wheels[:4]):
            setattr(row, f"wheel{i + 1}_speed", w)
        # wheel rates average the last window edge to edge: they describe the flow half a window
        # before the frame, so the current uses the boat state of that instant
        sr = st
        if self.rate_lag_s:
            sr = self._state(p.t - self.rate_lag_s, edge, live)
            if sr.heading is None or sr.v_east is None:
                sr = st
        (ff, fs), ambiguous = comp.current_lsq(wheels, self.angles, cal.wheel_noise)
        pf, ps = comp.current_paper(wheels, self.angles)
        cur = Current(row.t, cal.current_estimator, flow_fwd=ff, flow_stbd=fs)
        cur.ambiguous, cur.wheels = ambiguous, list(wheels)
        if moving:
            for name, (f, s) in (("lsq", (ff, fs)), ("paper", (pf, ps))):
                ce, cn = comp.current_over_ground(f, s, sr.heading, sr.v_east, sr.v_north)
                setattr(cur, f"east_{name}", ce)
                setattr(cur, f"north_{name}", cn)
                setattr(cur, f"speed_{name}", math.hypot(ce, cn))
                setattr(cur, f"dir_{name}", comp.to_direction(ce, cn))
            d = cal.current_estimator
            for k in ("east", "north", "speed", "dir"):
                setattr(cur, k, getattr(cur, f"{k}_{d}"))
            row.current_east, row.current_north = cur.east, cur.north
            row.current_speed, row.current_dir = cur.speed, cur.dir
            row.current_speed_paper, row.current_dir_paper = cur.speed_paper, cur.dir_paper
        self.out.write("/current", p.t, cur)

    # --- provenance -----------------------------------------------------------------------------

    def _provenance(self, row: Sample, labels: dict[str, str]) -> None:
        key = (tuple(labels.items()), tuple(self.nav.items()), self.bridge)
        if key in self._fed_keys:
            return
        self._fed_keys.add(key)
        nav = self.nav
        pos, vel, hdg = nav.get("position", ""), nav.get("velocity", ""), nav.get("heading", "")
        fed: dict[str, str] = {"lat": pos, "lon": pos, "sog": vel, "cog": vel, "heading": hdg}
        fed["yaw_rate"] = (
            nav.get("yaw_rate") or hdg
        )  # a rate-of-turn sensor, else the heading's slope
        fed["throttle"] = nav.get("throttle", "")
        for kind, cols in (
            ("depth", ("depth",)),
            ("temp", ("water_temp",)),
            ("stw", ("stw",)),
            ("app", ("app_wind_speed", "app_wind_angle")),
            ("true", ("wind_speed_instrument", "wind_dir_instrument")),
            ("attitude", ("roll", "pitch")),
        ):
            for c in cols:
                fed[c] = labels.get(kind, "")
        if labels.get("depth"):
            att = labels.get("attitude", "")
            fed["depth_raw"] = labels["depth"]
            if att and row.depth_raw is not None:
                fed["depth"] = f"{labels['depth']} + {att} (tilt corrected)"
            fed["bottom_lost"] = "import: the bottom lost (qa.depth.bottom_lost)"
        app, stw = labels.get("app"), labels.get("stw")
        wind = f"{app} + {hdg} + {vel}" if app else labels.get("wind_from_instrument", "")
        for c in ("wind_speed", "wind_dir", "wind_east", "wind_north"):
            fed[c] = wind
        set_drift = f"{stw} + {hdg} + {vel}" if stw else ""
        fed["current_speed_stw"] = fed["current_dir_stw"] = set_drift
        cur = "bridge paddle wheels + " + f"{hdg} + {vel}" if self.bridge else set_drift
        for c in ("current_speed", "current_dir", "current_east", "current_north"):
            fed[c] = cur
        if self.bridge:
            for c in ("current_speed_paper", "current_dir_paper") + tuple(
                f"wheel{i}_speed" for i in range(1, 5)
            ):
                fed[c] = "bridge paddle wheels"
        changed = False
        for col, label in fed.items():
            if label and getattr(row, col) is not None:
                seen = self.columns.setdefault(col, set())
                if label not in seen:
                    seen.add(label)
                    changed = True
        if changed:
            self.out.metadata(
                "columns", {c: "; ".join(sorted(v)) for c, v in sorted(self.columns.items())}
            )
