"""Bytes from the three instruments in, timed and compensated messages out: the daemon's core.

    pipe = Pipeline(calibration, sink)            # sink: .write(topic, log_time_ns, msg), .metadata(name, data)
    pipe.feed("bridge", t_mono_ns, t_wall_ns, chunk)   # "bridge", "depth" (NMEA) or "mavlink"
    pipe.gap("bridge", t_wall_ns, "port closed")
    pipe.flush(); pipe.close()

One timeline: host wall time, from device clocks by fitted mappings (forcemap.host.timesync), corrected to GPS
UTC once the autopilot reports it. Each bridge SAMPLE waits in a short queue until the autopilot
stream has passed its time, so the boat state can be interpolated at the sample's own time.

Topics (schemas in forcemap.host.schemas; log time = best estimate of the event's UTC):
raw ``/bridge/frame``, ``/bridge/hello``, ``/bridge/status``, ``/nmea/sentence``, ``/mavlink/<MSGNAME>``;
derived ``/boat/state``, ``/wind/apparent``, ``/wind/true``, ``/current`` (both estimators), ``/depth``
(also MTW water temperature), ``/fix`` (foxglove.LocationFix), ``/timesync``, ``/diagnostics`` and
``/samples`` (one samples-table row per bridge SAMPLE, docs/CONVENTIONS.md). Metadata:
``calibration``, ``config``, ``hello``.
"""

from __future__ import annotations

import math
import traceback
from collections import Counter, deque
from dataclasses import dataclass
from typing import Any, Protocol

from forcemap.host import compensation as comp
from forcemap.host import mavlink as mav
from forcemap.host.calibration import Calibration
from forcemap.host.nmea import LineSplitter, NmeaParser, Sentence, depth_below_surface
from forcemap.host.pulses import PulseTracker
from forcemap.host.schemas import SAMPLE_COLUMNS, location_fix
from forcemap.host.state import StateEstimator
from forcemap.host.timesync import SourceClock, UtcFix, WallClock
from forcemap.host.vane import VaneDecoder
from forcemap.protocol import wire

SOURCES = ("bridge", "depth", "mavlink")
# longest a sample waits for the autopilot stream before it goes out with what is known
HOLD_S = 3.0
DEPTH_MAX_AGE_S = 5.0
TEMP_MAX_AGE_S = 60.0
DIAG_PERIOD_S = 1.0


class Sink(Protocol):
    def write(self, topic: str, log_time_ns: int, message: dict) -> None: ...

    def metadata(self, name: str, data: dict[str, str]) -> None: ...


class NullSink:
    """Discards everything; counts messages per topic (for benchmarks and tests)."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()

    def write(self, topic: str, log_time_ns: int, message: dict) -> None:
        self.counts[topic] += 1

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.counts["metadata:" + name] += 1


class ListSink:
    """Keeps everything in memory: ``messages`` as (topic, log_time_ns, message), ``meta``."""

    def __init__(self) -> None:
        self.messages: list[tuple[str, int, dict]] = []
        self.meta: list[tuple[str, dict[str, str]]] = []

    def write(self, topic: str, log_time_ns: int, message: dict) -> None:
        self.messages.append((topic, log_time_ns, message))

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.meta.append((name, data))

    def topic(self, name: str) -> list[dict]:
        return [m for t, _, m in self.messages if t == name]


@dataclass(slots=True)
class _Pending:
    t: float  # host wall seconds
    app_speed: float | None
    app_angle: float | None
    wheels: list[float]


class Pipeline:
    """Parsing, clock alignment and compensation for the bridge, the depth sounder and the autopilot."""

    def __init__(
        self,
        calibration: Calibration | None = None,
        sink: Sink | None = None,
        *,
        sync: str | None = None,
        config: dict[str, str] | None = None,
        diagnostics_period_s: float = DIAG_PERIOD_S,
        rate_window_s: float | None = None,
        rate_lag: bool = True,
        hold_s: float = HOLD_S,
    ) -> None:
        self.cal = cal = calibration if calibration is not None else Calibration()
        self.sink = sink if sink is not None else NullSink()
        self.sync = sync or cal.sync
        self.hold_s = hold_s
        self.state = StateEstimator(self.sync, cal.max_state_gap_s)
        self.angles = [w.angle_deg for w in cal.wheels]
        self.ppm = [w.pulses_per_m for w in cal.wheels]
        comp.LsqGeometry(self.angles)  # fail now on a degenerate wheel geometry

        self.bridge_dec = wire.StreamDecoder()
        rate_window_s = cal.rate_window_s if rate_window_s is None else rate_window_s
        self.pulses = PulseTracker(window_us=int(rate_window_s * 1e6))
        self.rate_lag_s = rate_window_s / 2 if rate_lag else 0.0
        self.vane = VaneDecoder(
            cal.vane_table,
            cal.vane_vref,
            cal.vane_pullup_ohm,
            adc_ref=cal.vane_adc_ref,
            mounting_offset=cal.vane_offset_deg,
        )
        self.lines = LineSplitter()
        self.nmea = NmeaParser()
        self.mav = mav.MavlinkDecoder()

        self.clock_bridge = SourceClock("bridge")
        self.clock_mav = SourceClock("mavlink")
        self.utc = UtcFix()
        self.wall = WallClock()
        self.vehicle: tuple[int, int] | None = None

        self.pending: deque[_Pending] = deque()
        self.depth: tuple[float, float] | None = None  # (t, m)
        self.water_temp: tuple[float, float] | None = None
        self.dpt_t = -math.inf
        self.variation: float | None = cal.magnetic_variation_deg
        self.mav_nav = False
        self.last_fix: dict[str, Any] | None = None
        self.now = 0.0  # latest host wall time seen on any source
        self.counts: Counter[str] = Counter()
        self.errors: Counter[str] = Counter()
        self.last_error = ""
        self.gaps: list[dict[str, Any]] = []
        self.hellos: dict[int, dict] = {}
        self.hello_mismatch: list[str] = []
        self._diag_t: float | None = None
        self._rate_ref: tuple[float, dict[str, int]] | None = None
        self.rates: dict[str, float] = {}
        self.diag_period_s = diagnostics_period_s
        self.closed = False

        self.sink.metadata("calibration", cal.as_metadata())
        meta = {"sync": self.sync, "current_estimator": cal.current_estimator}
        if config:
            meta.update({str(k): str(v) for k, v in config.items()})
        self.sink.metadata("config", meta)

    # --- the contract ------------------------------------------------------------------------------

    def feed(self, source: str, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None:
        """Bytes as read from ``source``, stamped on arrival. Never raises."""
        try:
            mono, wall = t_mono_ns * 1e-9, t_wall_ns * 1e-9
            self.wall.observe(mono, wall)
            if wall > self.now:
                self.now = wall
            self.counts[source + "_bytes"] += len(data)
            if source == "bridge":
                self._feed_bridge(mono, t_mono_ns, t_wall_ns, data)
            elif source == "depth":
                self._feed_nmea(wall, t_mono_ns, t_wall_ns, data)
            elif source == "mavlink":
                self._feed_mavlink(mono, data)
            else:
                self.errors["unknown_source"] += 1
                return
            self._drain(final=False)
            self._maybe_diagnostics()
        except Exception:
            self.errors[source + "_internal"] += 1
            self.last_error = traceback.format_exc(limit=3)

    def gap(self, source: str, t_wall_ns: int, reason: str) -> None:
        """A source disconnected or reconnected: logged; partial frames and lines are dropped."""
        try:
            t = t_wall_ns * 1e-9
            if source == "bridge":
                self.bridge_dec = _carry_counts(self.bridge_dec)
            elif source == "depth":
                self.lines = LineSplitter()
            elif source == "mavlink":
                self.mav.reset()
            event = {"t": t, "source": source, "reason": str(reason)}
            self.gaps.append(event)
            self.counts[source + "_gaps"] += 1
            self.sink.write(
                "/diagnostics",
                self._log_ns(t),
                {"t": t, "counters": self.counters(), "event": event},
            )
        except Exception:
            self.errors[source + "_internal"] += 1
            self.last_error = traceback.format_exc(limit=3)

    def counters(self) -> dict[str, Any]:
        """Per-source counts and rates, rejections by reason, bad CRCs, the last fix, clock fits."""
        bd = self.bridge_dec
        boot = self.pulses.boot
        mb = self.clock_bridge.mapping()
        mm = self.clock_mav.mapping()
        return {
            "bridge": {
                "bytes": self.counts["bridge_bytes"],
                "frames": self.counts["bridge_frames"],
                "samples": self.counts["bridge_samples"],
                "rejected": dict(bd.rejects) | {"total": sum(bd.rejects.values())},
                "lost_frames": boot.lost_frames if boot else 0,
                "resets": self.pulses.resets,
                "vane_rejected": self.vane.rejected,
                "rate_hz": self.rates.get("bridge", 0.0),
                "gaps": self.counts["bridge_gaps"],
                "hello_differs_from_config": self.hello_mismatch,
            },
            "depth": {
                **self.nmea.counters(),
                "bytes": self.counts["depth_bytes"],
                "rate_hz": self.rates.get("depth", 0.0),
                "gaps": self.counts["depth_gaps"],
            },
            "mavlink": {
                **self.mav.counters(),
                "rate_hz": self.rates.get("mavlink", 0.0),
                "gaps": self.counts["mavlink_gaps"],
                "vehicle": list(self.vehicle) if self.vehicle else None,
            },
            "samples": {
                "emitted": self.counts["samples"],
                "pending": len(self.pending),
                "without_state": self.counts["samples_without_state"],
            },
            "last_fix": self.last_fix,
            "timesync": {
                "bridge": mb.as_message() if mb else None,
                "mavlink": mm.as_message() if mm else None,
                "utc_correction_s": self.utc.correction,
            },
            "errors": dict(self.errors),
        }

    def flush(self) -> None:
        """Emit what is complete, and samples that waited longer than ``hold_s`` for the autopilot."""
        try:
            self._drain(final=False)
        except Exception:
            self.errors["flush_internal"] += 1
            self.last_error = traceback.format_exc(limit=3)

    def close(self) -> None:
        """Emit everything still queued with what is known, and a last /diagnostics."""
        if self.closed:
            return
        self.closed = True
        try:
            for line in self.lines.flush():
                self._nmea_line(line, self.now, None, int(self.now * 1e9))
            self._drain(final=True)
            self._diagnostics(self.now)
        except Exception:
            self.errors["close_internal"] += 1
            self.last_error = traceback.format_exc(limit=3)

    # --- time --------------------------------------------------------------------------------------

    def _log_ns(self, wall_s: float) -> int:
        return max(0, int(round(self.utc.to_utc(wall_s) * 1e9)))

    def _emit_mapping(self, mapping: Any) -> None:
        if mapping is None:
            return
        msg = mapping.as_message()
        msg["kind"] = "device"
        self.sink.write("/timesync", self._log_ns(self.now), msg)

    # --- bridge ------------------------------------------------------------------------------------

    def _feed_bridge(self, mono: float, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None:
        for fr in self.bridge_dec.feed(data):
            try:
                self._frame(fr, mono, t_mono_ns, t_wall_ns)
            except Exception:  # a bug on one frame must not lose the rest of the read
                self._internal("bridge")

    def _internal(self, source: str) -> None:
        self.errors[source + "_internal"] += 1
        self.last_error = traceback.format_exc(limit=3)

    def _frame(self, fr: wire.Frame, mono: float, t_mono_ns: int, t_wall_ns: int) -> None:
        self.counts["bridge_frames"] += 1
        dev_s = fr.t_us * 1e-6
        host_mono, mapping = self.clock_bridge.observe(dev_s, mono, key=fr.boot_id)
        self._emit_mapping(mapping)
        t = self.wall.to_wall(host_mono)
        log_ns = self._log_ns(t)
        tname = wire.TYPE_NAMES.get(fr.msg_type, str(fr.msg_type))
        self.sink.write("/bridge/frame", log_ns, {
            "boot_id": fr.boot_id, "seq": fr.seq, "t_us": fr.t_us, "type": tname, "flags": fr.flags,
            "fields": fr.fields, "t_host": t, "t_mono_ns": t_mono_ns, "t_wall_ns": t_wall_ns,
        })  # fmt: skip
        rates = self.pulses.update(fr)
        if fr.msg_type == wire.HELLO:
            self.hellos[fr.boot_id] = fr.fields
            self._check_hello(fr.fields)
            msg = {
                "boot_id": fr.boot_id,
                "fields": fr.fields,
                "t_mono_ns": t_mono_ns,
                "t_wall_ns": t_wall_ns,
            }
            self.sink.write("/bridge/hello", log_ns, msg)
            self.sink.metadata(
                "hello",
                {"boot_id": str(fr.boot_id), **{k: str(v) for k, v in fr.fields.items()}},
            )
        elif fr.msg_type == wire.STATUS:
            msg = {
                "boot_id": fr.boot_id,
                "fields": fr.fields,
                "t_mono_ns": t_mono_ns,
                "t_wall_ns": t_wall_ns,
            }
            self.sink.write("/bridge/status", log_ns, msg)
        elif fr.msg_type == wire.SAMPLE and rates:
            self._sample(t, fr, rates)

    def _check_hello(self, hello: dict) -> None:
        """boat.toml is authoritative; a board that reports other constants is worth a warning."""
        cal = self.cal
        bad = []
        hz = hello.get("anemo_hz_per_mps") or 0.0
        if hz > 0 and abs(1.0 / hz - cal.anemo_mps_per_hz) > 0.01 * cal.anemo_mps_per_hz:
            bad.append("anemometer.mps_per_hz")
        for i, ppm in enumerate(hello.get("wheel_pulses_per_m") or ()):
            if (
                i < len(cal.wheels)
                and ppm > 0
                and abs(ppm - cal.wheels[i].pulses_per_m) > 0.01 * ppm
            ):
                bad.append(f"wheels[{i}].pulses_per_m")
        self.hello_mismatch = bad

    def _sample(self, t: float, fr: wire.Frame, rates: list) -> None:
        cal = self.cal
        self.counts["bridge_samples"] += 1
        anemo_hz = rates[0].rate_hz
        vane_raw = fr.fields["vane_raw"]
        angle = self.vane.decode(vane_raw)
        speed = comp.apparent_wind_speed(anemo_hz, cal.anemo_mps_per_hz, cal.anemo_min_speed)
        wheels = [
            comp.wheel_speed(r.rate_hz, self.ppm[i], cal.wheel_min_speed)
            for i, r in enumerate(rates[1:5])
        ]
        self.sink.write("/wind/apparent", self._log_ns(t), {
            "t": t, "speed": speed, "angle": angle, "rate_hz": anemo_hz, "vane_raw": vane_raw, "source": "bridge",
        })  # fmt: skip
        self.pending.append(_Pending(t, speed, angle, wheels))

    def _drain(self, final: bool) -> None:
        pend = self.pending
        if not pend:
            return
        covered = self.state.covered_until()
        while pend:
            p = pend[0]
            ready = (
                final or (covered is not None and covered >= p.t) or self.now - p.t > self.hold_s
            )
            if not ready:
                break
            pend.popleft()
            self._emit_sample(p, edge=final or covered is None or covered < p.t)

    def _emit_sample(self, p: _Pending, edge: bool) -> None:
        cal = self.cal
        st = self.state.at(p.t, edge=edge)
        log_ns = self._log_ns(p.t)
        row: dict[str, Any] = dict.fromkeys(SAMPLE_COLUMNS)
        row["t"] = log_ns * 1e-9
        row["lat"], row["lon"] = st.lat, st.lon
        row["heading"], row["yaw_rate"] = st.heading, st.yaw_rate
        row["sog"], row["cog"] = st.sog, st.cog
        row["throttle"] = st.throttle
        if self.depth is not None and abs(p.t - self.depth[0]) <= DEPTH_MAX_AGE_S:
            row["depth"] = self.depth[1]
        if self.water_temp is not None and abs(p.t - self.water_temp[0]) <= TEMP_MAX_AGE_S:
            row["water_temp"] = self.water_temp[1]
        row["app_wind_speed"], row["app_wind_angle"] = p.app_speed, p.app_angle
        for i, w in enumerate(p.wheels):
            row[f"wheel{i + 1}_speed"] = w
        moving = st.heading is not None and st.v_east is not None and st.v_north is not None
        if not moving:
            self.counts["samples_without_state"] += 1
        if moving and p.app_speed is not None and p.app_angle is not None:
            we, wn = comp.true_wind(p.app_speed, p.app_angle, st.heading, st.v_east, st.v_north)
            row["wind_east"], row["wind_north"] = we, wn
            row["wind_speed"] = math.hypot(we, wn)
            row["wind_dir"] = comp.from_direction(we, wn)
            self.sink.write("/wind/true", log_ns, {
                "t": row["t"], "speed": row["wind_speed"], "dir": row["wind_dir"], "east": we, "north": wn,
                "app_speed": p.app_speed, "app_angle": p.app_angle, "heading": st.heading,
                "boat_east": st.v_east, "boat_north": st.v_north, "source": "bridge",
            })  # fmt: skip
        # wheel rates average the last window edge to edge: they describe the flow half a window
        # before the frame, so the current uses the boat state of that instant
        if self.rate_lag_s:
            sr = self.state.at(p.t - self.rate_lag_s, edge=edge)
            if sr.heading is None or sr.v_east is None:
                sr = st
        else:
            sr = st
        (ff, fs), ambiguous = comp.current_lsq(p.wheels, self.angles, cal.wheel_noise)
        pf, ps = comp.current_paper(p.wheels, self.angles)
        cur: dict[str, Any] = {
            "t": row["t"],
            "estimator": cal.current_estimator,
            "flow_fwd": ff,
            "flow_stbd": fs,
            "ambiguous": ambiguous,
            "wheels": list(p.wheels),
        }
        if moving:
            for name, (f, s) in (("lsq", (ff, fs)), ("paper", (pf, ps))):
                ce, cn = comp.current_over_ground(f, s, sr.heading, sr.v_east, sr.v_north)
                cur[f"east_{name}"], cur[f"north_{name}"] = ce, cn
                cur[f"speed_{name}"] = math.hypot(ce, cn)
                cur[f"dir_{name}"] = comp.to_direction(ce, cn)
            d = cal.current_estimator
            for k in ("east", "north", "speed", "dir"):
                cur[k] = cur[f"{k}_{d}"]
            row["current_east"], row["current_north"] = cur["east"], cur["north"]
            row["current_speed"], row["current_dir"] = cur["speed"], cur["dir"]
            row["current_speed_paper"], row["current_dir_paper"] = (
                cur["speed_paper"],
                cur["dir_paper"],
            )
        self.sink.write("/current", log_ns, cur)
        self.sink.write("/samples", log_ns, row)
        self.counts["samples"] += 1

    # --- NMEA --------------------------------------------------------------------------------------

    def _feed_nmea(self, wall: float, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None:
        for line in self.lines.feed(data):
            try:
                self._nmea_line(line, wall, t_mono_ns, t_wall_ns)
            except Exception:
                self._internal("depth")

    def _nmea_line(self, line: bytes, t: float, t_mono_ns: int | None, t_wall_ns: int) -> None:
        s = self.nmea.parse(line)
        if s is None:
            return
        log_ns = self._log_ns(t)
        msg = s.as_message()
        msg["t_mono_ns"], msg["t_wall_ns"] = t_mono_ns, t_wall_ns
        self.sink.write("/nmea/sentence", log_ns, msg)
        if s.valid and s.data:
            self._nmea_values(s, t, log_ns)

    def _nmea_values(self, s: Sentence, t: float, log_ns: int) -> None:
        ty, d = s.type, s.data
        if ty in ("DPT", "DBT"):
            depth = depth_below_surface(s, self.cal.depth_offset_m)
            if depth is not None:
                # DPT says where its transducer is; DBT counts only when no DPT came lately
                if ty == "DPT":
                    self.dpt_t = t
                if ty == "DPT" or t - self.dpt_t > DEPTH_MAX_AGE_S:
                    self.depth = (t, depth)
                self.sink.write(
                    "/depth",
                    log_ns,
                    {"t": log_ns * 1e-9, "depth": depth, "water_temp": None, "sentence": ty},
                )
            return
        if ty == "MTW":
            if d["water_temp"] is not None:
                self.water_temp = (t, d["water_temp"])
                self.sink.write("/depth", log_ns, {"t": log_ns * 1e-9, "depth": None, "water_temp": d["water_temp"],
                                                   "sentence": ty})  # fmt: skip
            return
        if (
            ty in ("RMC", "HDG")
            and d.get("variation") is not None
            and self.cal.magnetic_variation_deg is None
        ):
            self.variation = d["variation"]
        if self.mav_nav:
            return  # the autopilot is the navigation source when there is one
        if ty == "RMC" and d["status"] == "A" and d["lat"] is not None:
            self._nmea_fix(t, log_ns, d["lat"], d["lon"], d["sog"], d["cog"])
        elif ty == "GGA" and d["lat"] is not None and d.get("quality"):
            self._nmea_fix(t, log_ns, d["lat"], d["lon"], None, None, d.get("alt") or 0.0)
        elif ty == "GLL" and d["status"] == "A" and d["lat"] is not None:
            self._nmea_fix(t, log_ns, d["lat"], d["lon"], None, None)
        elif ty == "VTG" and d["sog"] is not None:
            self._nmea_velocity(t, d["sog"], d["cog"])
        elif ty == "HDT" and d["heading"] is not None:
            self.state.add_heading(t, d["heading"])
        elif ty in ("HDM", "HDG") and d["heading_mag"] is not None and self.variation is not None:
            self.state.add_heading(
                t, d["heading_mag"] + (d.get("deviation") or 0.0) + self.variation
            )
        elif ty == "VHW" and d["heading"] is not None:
            self.state.add_heading(t, d["heading"])
        elif ty in ("MWV", "VWR"):
            self._nmea_wind(s, t, log_ns)

    def _nmea_fix(
        self,
        t: float,
        log_ns: int,
        lat: float,
        lon: float,
        sog: float | None,
        cog: float | None,
        alt: float = 0.0,
    ) -> None:
        if sog is not None:
            self.state.add_position_sog_cog(t, lat, lon, sog, cog)
        else:
            last = self.state.position.v[-1] if self.state.position.v else None
            self.state.add_position(
                t, lat, lon, last[2] if last else None, last[3] if last else None
            )
        self._fix(log_ns, lat, lon, alt, None)
        self.sink.write(
            "/boat/state", log_ns, self.state.at(t, edge=True).as_message() | {"source": "nmea"}
        )

    def _nmea_velocity(self, t: float, sog: float, cog: float | None) -> None:
        last = self.state.position.v[-1] if self.state.position.v else None
        if last is None:
            return
        ve, vn = (
            comp.velocity(sog, cog)
            if cog is not None
            else ((0.0, 0.0) if sog == 0 else (None, None))
        )
        self.state.add_position(t, last[0], last[1], ve, vn)

    def _nmea_wind(self, s: Sentence, t: float, log_ns: int) -> None:
        d = s.data
        if s.type == "MWV" and (d["reference"] != "R" or d["status"] != "A"):
            return
        if d["angle"] is None or d["speed"] is None:
            return
        self.sink.write(
            "/wind/apparent",
            log_ns,
            {
                "t": log_ns * 1e-9,
                "speed": d["speed"],
                "angle": d["angle"],
                "rate_hz": None,
                "vane_raw": None,
                "source": "nmea",
            },
        )
        st = self.state.at(t, edge=True)
        if st.heading is None or st.v_east is None or st.v_north is None:
            return
        we, wn = comp.true_wind(d["speed"], d["angle"], st.heading, st.v_east, st.v_north)
        self.sink.write("/wind/true", log_ns, {
            "t": log_ns * 1e-9, "speed": math.hypot(we, wn), "dir": comp.from_direction(we, wn), "east": we,
            "north": wn, "app_speed": d["speed"], "app_angle": d["angle"], "heading": st.heading,
            "boat_east": st.v_east, "boat_north": st.v_north, "source": "nmea",
        })  # fmt: skip

    # --- MAVLink -----------------------------------------------------------------------------------

    def _feed_mavlink(self, mono: float, data: bytes) -> None:
        msgs = self.mav.feed(data)
        if not msgs:
            return
        wall_of = self.wall.to_wall
        for m in msgs:
            try:
                self._mav_message(m, mono, wall_of)
            except Exception:
                self._internal("mavlink")

    def _mav_message(self, m: Any, mono: float, wall_of: Any) -> None:
        ty = m.get_type()
        if self.vehicle is None and ty == "HEARTBEAT":
            self.vehicle = mav.vehicle_of(m)
        vehicle = mav.is_vehicle(m, self.vehicle)
        t_mono = mono
        tb = getattr(m, "time_boot_ms", None) if vehicle else None
        if tb is not None:
            t_mono, mapping = self.clock_mav.observe(tb * 1e-3, mono)
            self._emit_mapping(mapping)
        t = wall_of(t_mono)
        if ty == "SYSTEM_TIME" and vehicle and m.time_unix_usec:
            if self.utc.observe(m.time_unix_usec * 1e-6, t):
                self.sink.write("/timesync", self._log_ns(t), {
                    "source": "mavlink", "epoch": "utc", "offset_s": self.utc.correction, "drift_ppm": 0.0,
                    "ref_device_s": 0.0, "points": len(self.utc.diffs), "span_s": 0.0, "kind": "utc",
                })  # fmt: skip
        log_ns = self._log_ns(t)
        self.sink.write("/mavlink/" + ty, log_ns, mav.raw_dict(m))
        if vehicle and ty in mav.USED:
            self._mav_values(ty, mav.to_si(m), t, log_ns)

    def _mav_values(self, ty: str, d: dict[str, Any] | None, t: float, log_ns: int) -> None:
        if d is None:
            return
        st = self.state
        if ty == "ATTITUDE":
            self._take_nav()
            st.add_heading(t, d["heading"], d["yaw_rate"])
        elif ty == "GLOBAL_POSITION_INT":
            if d["lat"] == 0.0 and d["lon"] == 0.0:
                return  # no position yet
            self._take_nav()
            self.counts["mav_gpi"] += 1
            st.add_position(t, d["lat"], d["lon"], d["v_east"], d["v_north"])
            self._fix(log_ns, d["lat"], d["lon"], d["alt"], None)
            self.sink.write(
                "/boat/state", log_ns, st.at(t, edge=True).as_message() | {"source": "mavlink"}
            )
        elif ty == "GPS_RAW_INT":
            if d["fix_type"] >= 2 and self.counts["mav_gpi"] == 0:
                self._take_nav()
                st.add_position_sog_cog(t, d["lat"], d["lon"], d["sog"], d["cog"])
                self._fix(log_ns, d["lat"], d["lon"], d["alt"], d["eph"])
        elif ty == "VFR_HUD":
            st.add_throttle(t, d["throttle"])

    def _take_nav(self) -> None:
        if not self.mav_nav:
            self.mav_nav = True
            self.state.reset()  # drop NMEA navigation: the autopilot's is better

    def _fix(self, log_ns: int, lat: float, lon: float, alt: float, h_acc: float | None) -> None:
        self.last_fix = {"t": log_ns * 1e-9, "lat": lat, "lon": lon}
        self.sink.write("/fix", log_ns, location_fix(log_ns, lat, lon, alt, h_acc))

    # --- diagnostics -------------------------------------------------------------------------------

    def _maybe_diagnostics(self) -> None:
        if self._diag_t is None:
            self._diag_t = self.now
            self._rate_ref = (self.now, self._totals())
            return
        if self.now - self._diag_t >= self.diag_period_s:
            self._diagnostics(self.now)

    def _totals(self) -> dict[str, int]:
        return {
            "bridge": self.counts["bridge_frames"],
            "depth": self.nmea.lines,
            "mavlink": sum(self.mav.messages.values()),
        }

    def _diagnostics(self, t: float) -> None:
        tot = self._totals()
        if self._rate_ref is not None:
            t0, ref = self._rate_ref
            if t > t0:
                self.rates = {k: (tot[k] - ref[k]) / (t - t0) for k in tot}
        self._rate_ref = (t, tot)
        self._diag_t = t
        self.sink.write("/diagnostics", self._log_ns(t), {"t": t, "counters": self.counters()})


def _carry_counts(old: wire.StreamDecoder) -> wire.StreamDecoder:
    """A fresh decoder (partial frame dropped) that keeps the old one's counters."""
    new = wire.StreamDecoder()
    new.rejects, new.frames, new.bytes_in = old.rejects, old.frames, old.bytes_in
    return new
