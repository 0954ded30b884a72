"""The core loop: world, boat, autopilot and instruments stepped in virtual time, bytes out to a sink.

    sim = Simulation(scenario="river", mission="lawnmower", effects=["depth_current"], seed=0)
    sim.run(600.0, sink)     # sink(source, t_ns, data) with source in bridge, depth, mavlink, nmea

``t_ns`` is the virtual UNIX time in ns at which the bytes leave the instrument; calls come in
non-decreasing ``t_ns`` order. No transport and no host clock: offline it runs as fast as it can.
"""

from __future__ import annotations

import heapq
import math
import random
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel.boat import Boat, BoatParams, HullState
from forcemap.host.vessel.control import Controller, Gains, Navigator
from forcemap.host.vessel.geodesy import LocalFrame

from . import effects as fx
from . import faults as fl
from . import modes as md
from . import truth as truth_files
from .autopilot import Autopilot, nav_state
from .bridge_emu import EmulatedBridge
from .fields import World
from .instruments import InstrumentConfig, Readings, Sensors
from .jetyak import JETYAK, ROVER_GAINS
from .machine_emu import PWRON_RESET
from .mission_link import MissionLink
from .nmea_bus import BUS_BYTES_PER_S, Motion, NmeaBus, make_bus
from .nmea_sounder import BAUD_BYTES_PER_S, Garbler, Uart, heel_roll, make_sounder, transducer_tilt

Sink = Callable[[str, int, bytes], Any]
Progress = Callable[[float, float], Any]
# events(kind, source, t_ns): "unplug" and "plug" for cable pulls, "reset" for a board reset
Events = Callable[[str, str, int], Any]

DT = 0.05  # s, boat step (20 Hz)
TRUTH_EVERY = 2  # truth rows at 10 Hz
MAVLINK_BYTES_PER_S = 11_520.0  # 115200 baud telemetry port


class Simulation(MissionLink):
    """One simulated survey: scenario, mission, effects, faults and seed fix every byte it produces."""

    def __init__(
        self,
        scenario: str | sc.Scenario = "river",
        mission: str | ms.Mission | None = None,
        effects: str | list[str | fx.Effect] | None = None,
        faults: str | list[str | fl.Fault] | None = None,
        seed: int = 0,
        truth_dir: str | Path | None = None,
        *,
        bridge_writable: Callable[[], bool] | None = None,
        events: Events | None = None,
        instruments: bool = True,
        nmea_bus: bool = False,
        boat_params: BoatParams | None = None,
        gains: Gains | None = None,
        dt: float = DT,
    ) -> None:
        """`dt`: the boat's step; only a run without instruments may take a longer one (theirs is DT)."""
        if instruments and dt != DT:
            raise ValueError(f"the instruments step at {DT} s; dt={dt} needs instruments=False")
        self.scenario = sc.load(scenario)
        self.mission = ms.load(mission or "lawnmower", self.scenario)
        self.effects = fx.parse_list(self.scenario.default_effects if effects is None else effects)
        self.faults = fl.parse(faults)
        self.seed = seed
        self.truth_dir = truth_dir
        self.bridge_writable = bridge_writable
        self.events = events
        self.instruments = instruments  # False: world, boat and truth only (fast, no bytes)
        self.dt = float(dt)
        self.truth_every = max(1, round(TRUTH_EVERY * DT / self.dt))
        # the NMEA-only boat's bus (nmea_bus.py) on the "nmea" port: on request or with its faults
        self.bus_faults = {f.kind for f in self.faults if f.kind in fl.BUS_KINDS}
        self.nmea_bus = nmea_bus or bool(self.bus_faults)
        self.boat_params = boat_params or JETYAK  # the hull and jet flown (not the planner's)
        self.gains = gains or ROVER_GAINS  # the autopilot's tuning
        self.geo = LocalFrame(self.scenario.lat0, self.scenario.lon0)
        self.t0_ns = int(round(self.scenario.t0 * 1e9))
        self.world: World | None = None
        self.track: dict[str, np.ndarray] = {}
        self.fault_log: list[tuple[float, str, str]] = []  # (t s, kind, source) as they happened
        self.stats: dict[str, int] = {}

    # ---- set-up ---------------------------------------------------------------------------
    def _effect(self, name: str) -> dict[str, Any] | None:
        return next((e.params for e in self.effects if e.name == name), None)

    def start(self, duration_s: float, sink: Sink) -> None:
        """Build everything for a run of ``duration_s`` (the time-dependent effects scale with it)."""
        self.duration = float(duration_s)
        self.sink = sink
        tables = self.scenario.tables
        self.world = World(self.scenario, self.effects, self.duration, self.seed)
        wps = self.mission.waypoints
        a, b = wps[0], wps[1]
        psi = math.atan2(b[0] - a[0], b[1] - a[1]) % (2 * math.pi)
        self.boat = Boat(self.boat_params, HullState(x=float(a[0]), y=float(a[1]), psi=psi, u=1.5))
        self.cruise = float(tables.get("boat", {}).get("cruise_speed", 3.5))
        self.nav = Navigator(wps, self.gains, loop=self.mission.loop, speeds=self.mission.speeds)
        self.ctl = Controller(self.cruise, self.gains)
        self.mode = md.AUTO
        self.mode_changes = md.schedule(tables)
        self.mode_log: list[tuple[float, int]] = []  # (t s, mode) as it changed
        self.pilot = md.ModePilot((float(a[0]), float(a[1])), self.gains.wp_radius_m)
        self._build_devices(tables)
        self.damage = {
            s: fl.ByteDamage(s, self.faults, self.duration, self.seed) for s in fl.SOURCES
        }
        self.actions = fl.schedule(self.faults, self.duration)
        self.garbler: Garbler | None = None
        self.t = 0.0
        self.k = 0
        self.next_sound = 1.0
        self.next_progress = 0.0
        self.pulled: set[str] = set()
        self.rows: list[tuple[float, ...]] = []
        self.extra: list[tuple[float, ...]] = []
        self.throttle = 0.0
        self.psi_d, self.xte = psi, 0.0
        self.stats = dict.fromkeys(fl.SOURCES, 0)
        self._update_point()

    def _build_devices(self, tables: dict[str, Any]) -> None:
        """The instruments, the bridge, the autopilot and their serial links, as the scenario sets them up."""
        icfg = InstrumentConfig.from_table(tables.get("instruments", {}))
        mis = self._effect("wheel_misalignment")
        up = self._effect("anemometer_upwash")
        self.sensors = Sensors(
            icfg,
            seed=self.seed * 1000 + 11,
            misalign={int(mis["wheel"]) - 1: float(mis["angle_deg"])} if mis else {},
            upwash_k=float(up["k"]) if up else 0.0,
        )
        self.heap: list[tuple[int, int, str, bytes | None]] = []
        self._seq = 0
        self.bridge_on = True
        self.__dict__.pop("bridge", None)
        bcfg = tables.get("bridge", {})
        self.ppm = float(bcfg.get("clock_ppm", 25.0))
        self.bridge = EmulatedBridge(
            self._bridge_write,
            seed=self.seed * 1000 + 3,
            wheel_ppm=icfg.wheel_pulses_per_m,
            anemo_hz_per_mps=icfg.anemo_hz_per_mps,
            writable=self.bridge_writable,
        )
        self.pulses: list[list[int]] = [[] for _ in range(5)]
        self.boots: list[tuple[int, int]] = []
        self._note_boot()
        dev = self._effect("compass_deviation")
        apcfg = tables.get("autopilot", {})
        self.autopilot = Autopilot(
            self.geo,
            self.scenario.t0,
            seed=self.seed * 1000 + 5,
            boot_before_s=float(apcfg.get("boot_before_s", 6.0)),
            gps_fix_after_s=float(apcfg.get("gps_fix_after_s", 8.0)),
            deviation=(dev["amplitude_deg"], dev["phase_deg"]) if dev else None,
        )
        self.autopilot.uplink.accepted = self._mission_items()
        off = self._effect("clock_offset")
        self.mav_latency_ns = int(float(off["offset_s"]) * 1e9) if off else 0
        self.sounder = make_sounder(
            self.seed * 1000 + 7, tables.get("sounder", {}), self.faults, self.duration,
            self._effect("heel"),
        )  # fmt: skip
        self.roll = 0.0
        self.bus: NmeaBus | None = None
        if self.nmea_bus:
            self.bus = make_bus(self.geo, self.seed * 1000 + 13, self.scenario, self.faults)
            self.bus.calibration_faults(self.faults)
        self.uart_nmea = Uart(BUS_BYTES_PER_S, chunk=64)
        self.garble_rng = random.Random(self.seed * 1000 + 9)
        self.uart_depth = Uart(BAUD_BYTES_PER_S)
        self.uart_mav = Uart(MAVLINK_BYTES_PER_S, chunk=64)

    # ---- time bases -----------------------------------------------------------------------
    def _ns(self, t_s: float) -> int:
        return self.t0_ns + int(round(t_s * 1e9))

    def _bridge_us(self, t_s: float) -> int:
        """The bridge's timeline (its crystal runs ``ppm`` fast) at sim time ``t_s``."""
        return int(math.ceil(t_s * 1e6 * (1.0 + self.ppm * 1e-6)))

    def _bridge_write(self, data: bytes) -> int | None:
        bridge = getattr(self, "bridge", None)  # HELLO goes out while the bridge is being built
        t_s = (bridge.now_us if bridge is not None else 0) / (1e6 * (1.0 + self.ppm * 1e-6))
        if self.bridge_on:
            self._push(self._ns(t_s), "bridge", bytes(data))
        return len(data)

    def _push(self, t_ns: int, source: str, data: bytes | None) -> None:
        self._seq += 1
        heapq.heappush(self.heap, (t_ns, self._seq, source, data))

    def _flush(self, until_ns: int) -> None:
        heap, sink = self.heap, self.sink
        while heap and heap[0][0] <= until_ns:
            t_ns, _, source, data = heapq.heappop(heap)
            if isinstance(data, bytes):
                if source in self.pulled:
                    continue
                data = self.damage[source].apply((t_ns - self.t0_ns) * 1e-9, data)
                if data:
                    self.stats[source] += len(data)
                    sink(source, t_ns, data)
            else:
                # a port event, in time order with the bytes: bytes after an unplug are lost
                kind, src = source.split(":")
                if kind == "unplug":
                    self.pulled.add(src)
                elif kind == "plug":
                    self.pulled.discard(src)
                if self.events is not None:
                    self.events(kind, src, t_ns)

    # ---- the loop -------------------------------------------------------------------------
    def _update_point(self) -> None:
        s = self.boat.s
        self.p = self.world.at(s.x, s.y, self.t)  # type: ignore[union-attr]

    def _fault_actions(self, t_start: float, t_end: float) -> None:
        while self.actions and self.actions[0][0] <= t_end:
            at, act, f = self.actions.pop(0)
            at = max(at, t_start)
            src = f.source
            if act in ("unplug", "plug", "reset"):
                self.bridge.advance_to(max(self._bridge_us(at), self.bridge.now_us))
            if act == "unplug":
                if src == "bridge":
                    self.bridge_on = False
                self._push(self._ns(at), f"unplug:{src}", None)
            elif act == "plug":
                self._push(self._ns(at), f"plug:{src}", None)
                if src == "bridge":
                    self.bridge_on = True
                    self.bridge.reset(PWRON_RESET)  # the board was unpowered: it boots again
                    self._note_boot()
            elif act == "reset":
                self.bridge.reset(f.cause)
                self._note_boot()
                self._push(self._ns(at), "reset:bridge", None)
            elif act == "gps_off":
                self.autopilot.gps_lost = True
            elif act == "gps_on":
                self.autopilot.gps_lost = False
            elif act == "clock_jump":
                self.autopilot.time_jump_s += f.jump
            elif act == "garble_on":
                self.garbler = Garbler(self.garble_rng, f.rate)
            elif act == "garble_off":
                self.garbler = None
            self.fault_log.append((at, act, src))

    def step(self) -> None:
        """Advance one boat step (`dt`) with every instrument."""
        dt = self.dt
        p = self.p
        self.throttle, steer = self._steer(dt)
        t_prev = self.t
        self.k += 1
        t_new = self.k * dt
        self._fault_actions(t_prev, t_new)
        self.t = t_new
        self.boat.step(
            dt, self.throttle, steer, (p.current_east, p.current_north), (p.wind_east, p.wind_north)
        )
        s = self.boat.s
        self._update_point()
        p = self.p
        sog = math.hypot(s.ve, s.vn)
        # air relative to the boat in body axes (forward, starboard)
        sp, cp = math.sin(s.psi), math.cos(s.psi)
        rel_e, rel_n = p.wind_east - s.ve, p.wind_north - s.vn
        rel_f, rel_s = rel_e * sp + rel_n * cp, rel_e * cp - rel_n * sp
        truth = self.sensors.truth(s.u, s.v, s.r, rel_f, rel_s)
        heading_deg = math.degrees(s.psi) % 360.0
        self.roll = heel_roll(self._effect("heel"), truth.app_speed, truth.app_angle)
        if self.instruments:
            self._instruments(t_prev, t_new, truth, sog, heading_deg)
        if self.k % self.truth_every == 0:
            self.rows.append((
                t_new, s.x, s.y, heading_deg, math.degrees(s.r), sog, s.ve, s.vn, p.depth, p.water_temp,
                p.wind_east, p.wind_north, p.current_east, p.current_north, *truth.wheels,
                truth.app_speed, truth.app_angle,
            ))  # fmt: skip
            self.extra.append((self.xte, self.nav.legs_done, self.throttle, s.u, s.v, self.roll))
        self._flush(self._ns(t_new))

    def _instruments(
        self, t_prev: float, t_new: float, truth: Readings, sog: float, heading_deg: float
    ) -> None:
        """Bridge edges and firmware, the sounder's sentences and the autopilot's messages for one step."""
        s, p = self.boat.s, self.p
        # bridge: pulse edges for this step, the vane, then run the firmware up to the step's end
        u0, u1 = self._bridge_us(t_prev), self._bridge_us(t_new)
        u0 = max(u0, self.bridge.now_us)
        rates = self.sensors.rates(s.u, s.v, s.r, truth.app_speed, sog, DT)
        if self.bridge_on:
            for ch, times in enumerate(self.sensors.edges(rates, u0, u1)):
                if times:
                    self.bridge.add_edges(ch, times)
                    if self.truth_dir is not None:  # the ledger is truth; a live run keeps none
                        self.pulses[ch].extend(self.sensors.primary[ch])
            self.bridge.set_vane_voltage(self.sensors.vane_volts(truth.app_angle))
        self.bridge.advance_to(u1)
        if t_new + 1e-9 >= self.next_sound:
            self.next_sound += 1.0
            tilt = (0.0, 0.0, 0.0)
            if self.sounder.beam_deg is not None:
                tilt = transducer_tilt(self.world, s.x, s.y, heading_deg, self.roll)
            lines = self.sounder.sentences(p.depth, p.water_temp, t_new, tilt)
            if self.garbler is not None:
                lines = self.garbler.apply(lines)
            data = "".join(x + "\r\n" for x in lines).encode("ascii", "replace")
            for t_ns, piece in self.uart_depth.send(self._ns(t_new), data):
                self._push(t_ns, "depth", piece)
        if self.bus is not None:
            self._bus(t_new, heading_deg)
        nav = (
            t_new,
            heading_deg,
            s,
            self.nav,
            self.mission.seqs,
            self.throttle,
            self.xte,
            self.psi_d,
        )
        state = nav_state(*nav)
        state.roll_deg = self.roll
        msgs = self.autopilot.messages(state)
        msgs += self.autopilot.uplink_due(t_new)
        if msgs:
            for t_ns, piece in self.uart_mav.send(self._ns(t_new), b"".join(msgs)):
                self._push(t_ns + self.mav_latency_ns, "mavlink", piece)

    def _bus(self, t: float, heading_deg: float) -> None:
        """The NMEA bus's sentences for this step, paced at its baud rate."""
        s = self.boat.s
        m = Motion(self.scenario.t0 + t, s.x, s.y, heading_deg, math.degrees(s.r), s.ve, s.vn, s.u)
        lines = self.bus.step(m)  # type: ignore[union-attr]
        if lines:
            data = "".join(x + "\r\n" for x in lines).encode("ascii")
            for t_ns, piece in self.uart_nmea.send(self._ns(t), data):
                self._push(t_ns, "nmea", piece)

    def advance(self, t_s: float, progress: Progress | None = None) -> None:
        """Step until sim time ``t_s`` (s since the start), capped at the run's duration."""
        end = min(t_s, self.duration)
        while self.t + 0.5 * self.dt < end:
            self.step()
            if progress is not None and self.t >= self.next_progress:
                self.next_progress += 10.0
                progress(self.t, self.duration)

    def finish(self) -> None:
        """Flush every byte still queued and write the truth if a truth directory was given."""
        self._flush(2**62)
        self.track = truth_files.track_arrays(self.rows, self.extra)
        if self.truth_dir is not None:
            truth_files.write_all(self.truth_dir, self.meta(), self.world, self.truth_table())  # type: ignore[arg-type]
            truth_files.write_pulses(Path(self.truth_dir) / "pulses.npz", self.boots, self.pulses)
            truth_files.write_mission(Path(self.truth_dir), self.mission, self.geo)

    def _note_boot(self) -> None:
        self.boots.append((self.bridge.boot_id, self.bridge.boot_us))

    def run(self, duration_s: float, sink: Sink, progress: Progress | None = None) -> Simulation:
        """The whole survey, offline, as fast as it goes."""
        self.start(duration_s, sink)
        self.advance(duration_s, progress)
        self.finish()
        return self

    # ---- results --------------------------------------------------------------------------
    def truth_table(self) -> np.ndarray:
        """The samples.csv table: a row per 0.1 s (per step if longer), columns as ``truth.COLUMNS``."""
        track = self.track or truth_files.track_arrays(self.rows, self.extra)
        if track and self.world is not None:
            track["water_level"] = (
                np.asarray(self.world.water_level(track["t"]), float) + 0.0 * track["t"]
            )
        return truth_files.samples_table(track, self.geo, self.scenario.t0)

    def meta(self) -> dict[str, Any]:
        """What effects.json holds."""
        return truth_files.effects_meta(self)
