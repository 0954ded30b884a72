"""The autopilot's telemetry: MAVLink 2 from pymavlink's encoders at ArduPilot Rover's stream rates."""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from forcemap.host.vessel.boat import HullState
from forcemap.host.vessel.control import Navigator
from forcemap.host.vessel.geodesy import LocalFrame
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from .mission_protocol import MissionReceiver
from .modes import AUTO

# (message, period s): ArduPilot Rover's default SRx_ stream rates
RATES = {
    "HEARTBEAT": 1.0,
    "SYSTEM_TIME": 1.0,
    "GPS_RAW_INT": 0.2,
    "GLOBAL_POSITION_INT": 0.2,
    "ATTITUDE": 0.1,
    "VFR_HUD": 0.25,
    "MISSION_CURRENT": 1.0,  # EXTENDED_STATUS group
    "NAV_CONTROLLER_OUTPUT": 1.0,
}
ROVER_MODE_AUTO = AUTO
BASE_MODE = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
AUTO_FLAGS = mavlink2.MAV_MODE_FLAG_AUTO_ENABLED | mavlink2.MAV_MODE_FLAG_GUIDED_ENABLED
MANUAL_FLAGS = mavlink2.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED


@dataclass
class NavState:
    """What the autopilot knows at one instant (true values; noise is added here)."""

    t: float  # s since the run started
    x: float
    y: float
    heading_deg: float  # true heading of the bow
    yaw_rate: float  # rad/s clockwise
    ve: float
    vn: float
    throttle: float  # 0..1
    wp_seq: int = 1  # mission item the boat is heading for (MISSION_CURRENT)
    wp_total: int = 0
    xtrack: float = 0.0  # m, right of the track positive (NAV_CONTROLLER_OUTPUT.xtrack_error)
    nav_bearing_deg: float = 0.0  # the guidance's desired heading
    target_bearing_deg: float = 0.0  # bearing to the waypoint
    wp_dist: float = 0.0
    roll_deg: float = 0.0  # the hull's heel, starboard down positive (the `heel` effect)


def nav_state(
    t: float,
    heading_deg: float,
    s: HullState,
    nav: Navigator,
    seqs,
    throttle: float,
    xte: float,
    psi_d: float,
) -> NavState:  # type: ignore[no-untyped-def]
    """What the autopilot knows at ``t``: the hull's state and where the navigator is on the mission
    (``seqs``: the mission item of each waypoint, None for a mission not received over MAVLink)."""
    wx, wy = nav.wps[nav.leg]
    return NavState(
        t, s.x, s.y, heading_deg, s.r, s.ve, s.vn, throttle,
        wp_seq=int(seqs[nav.leg]) if seqs is not None else nav.leg + 1,
        wp_total=int(seqs[-1]) + 1 if seqs is not None else len(nav.wps) + 1,
        xtrack=xte,
        nav_bearing_deg=math.degrees(psi_d) % 360.0,
        target_bearing_deg=math.degrees(math.atan2(wx - s.x, wy - s.y)) % 360.0,
        wp_dist=math.hypot(wx - s.x, wy - s.y),
    )  # fmt: skip


@dataclass
class _Fix:
    """The autopilot's clocks and estimate at one instant, shared by the messages it sends then."""

    boot_ms: int
    unix_us: int
    has_fix: bool
    gx: float | None
    gy: float | None
    heading: float
    sog: float


class Autopilot:
    """Encodes the boat's state as the Pixhawk would send it; time fields are on the autopilot's clocks."""

    def __init__(
        self,
        geo: LocalFrame,
        t0_unix: float,
        seed: int = 0,
        boot_before_s: float = 6.0,
        gps_fix_after_s: float = 8.0,
        deviation: tuple[float, float] | None = None,
    ) -> None:
        self.geo = geo
        self.t0_unix = t0_unix
        self.rng = random.Random(seed)
        self.boot_before = boot_before_s
        self.fix_at = gps_fix_after_s
        self.deviation = deviation  # (amplitude deg, phase deg) of compass deviation
        self.mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        self.next_due = dict.fromkeys(RATES, 0.0)
        self._now: set[str] = set()
        self.gps_lost = False
        self.time_jump_s = 0.0  # a clock-jump fault steps the autopilot's clocks
        self._err = [0.0, 0.0]  # slowly wandering GPS position error (m)
        self._last_vel = (0.0, 0.0)
        self._dr: tuple[float, float] | None = None
        self._last_t = 0.0
        self.uplink = MissionReceiver()  # the mission protocol, vehicle side
        self.mode = AUTO  # HEARTBEAT custom_mode (sim_devices.modes)
        self._rx = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        self._rx.robust_parsing = True

    def receive(self, data: bytes, t: float) -> list[bytes]:
        """Bytes from the ground station at sim time ``t``; the encoded replies."""
        out: list[bytes] = []
        try:
            msgs = self._rx.parse_buffer(data) or []
        except Exception:  # pymavlink can raise on garbage; a real autopilot drops it
            self._rx = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
            self._rx.robust_parsing = True
            msgs = []
        for msg in msgs:
            if msg.get_type() != "BAD_DATA":
                out += [self._pack(r) for r in self.uplink.handle(msg, t)]
        return out

    def report_now(self, *names: str) -> None:
        """Send these messages at the next step too (a mode change, a new current item), as Rover
        does, without moving their regular schedule."""
        self._now.update(names)

    def uplink_due(self, t: float) -> list[bytes]:
        """The vehicle's own re-requests of a stalled upload."""
        return [self._pack(r) for r in self.uplink.tick(t)]

    def _pack(self, msg) -> bytes:  # type: ignore[no-untyped-def]
        buf = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        return bytes(buf)

    def _heading(self, true_deg: float) -> float:
        if self.deviation is None:
            return true_deg % 360.0
        a, ph = self.deviation
        return (true_deg + a * math.sin(math.radians(true_deg + ph))) % 360.0

    def messages(self, s: NavState) -> list[bytes]:
        """Every message due at ``s.t``, encoded."""
        fix = self._fix(s)
        out: list[bytes] = []
        for name, period in RATES.items():
            if s.t + 1e-9 >= self.next_due[name]:
                self.next_due[name] = max(self.next_due[name] + period, s.t)
            elif name not in self._now:
                continue
            self._now.discard(name)
            out.append(self._pack(getattr(self, f"_{name.lower()}")(s, fix)))
        return out

    def _fix(self, s: NavState) -> _Fix:
        """The autopilot's clocks and its position estimate at ``s.t`` (the GPS error wanders on)."""
        dt = s.t - self._last_t
        self._last_t = s.t
        k = min(dt / 30.0, 1.0)
        for i in range(2):
            self._err[i] += k * (
                self.rng.gauss(0.0, 0.5) * math.sqrt(2.0 / max(k, 1e-9)) - self._err[i]
            )
        boot_ms = int((s.t + self.boot_before + self.time_jump_s) * 1000.0)
        has_fix = s.t >= self.fix_at and not self.gps_lost
        unix_us = int((self.t0_unix + s.t + self.time_jump_s) * 1e6) if s.t >= self.fix_at else 0
        if has_fix:
            gx, gy = s.x + self._err[0], s.y + self._err[1]
            self._dr = (gx, gy)
            self._last_vel = (s.ve, s.vn)
        elif self._dr is not None:
            # no GPS: the estimate coasts on the last GPS velocity and drifts off the true track
            self._dr = (self._dr[0] + self._last_vel[0] * dt, self._dr[1] + self._last_vel[1] * dt)
            gx, gy = self._dr
        else:
            gx = gy = None
        heading = self._heading(s.heading_deg + self.rng.gauss(0.0, 0.3))
        return _Fix(boot_ms, unix_us, has_fix, gx, gy, heading, math.hypot(s.ve, s.vn))

    def _heartbeat(self, s: NavState, f: _Fix):  # type: ignore[no-untyped-def]
        return self.mav.heartbeat_encode(
            mavlink2.MAV_TYPE_SURFACE_BOAT,
            mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
            BASE_MODE | (AUTO_FLAGS if self.mode == AUTO else MANUAL_FLAGS),
            self.mode,
            mavlink2.MAV_STATE_ACTIVE,
        )

    def _system_time(self, s: NavState, f: _Fix):  # type: ignore[no-untyped-def]
        return self.mav.system_time_encode(f.unix_us, f.boot_ms)

    def _gps_raw_int(self, s: NavState, f: _Fix):  # type: ignore[no-untyped-def]
        if not f.has_fix:
            return self.mav.gps_raw_int_encode(f.unix_us, 1, 0, 0, 0, 9999, 9999, 0, 65535, 0)
        lat, lon = self.geo.to_latlon(f.gx, f.gy)
        cog = math.degrees(math.atan2(s.ve, s.vn)) % 360.0
        return self.mav.gps_raw_int_encode(
            f.unix_us, 3, int(round(float(lat) * 1e7)), int(round(float(lon) * 1e7)), 45_000,
            90, 150, int(round(f.sog * 100)), int(round(cog * 100)) % 36000, 14,
        )  # fmt: skip

    def _global_position_int(self, s: NavState, f: _Fix):  # type: ignore[no-untyped-def]
        lat, lon = (0.0, 0.0) if f.gx is None else self.geo.to_latlon(f.gx, f.gy)
        return self.mav.global_position_int_encode(
            f.boot_ms, int(round(float(lat) * 1e7)), int(round(float(lon) * 1e7)), 45_000, 0,
            int(round(s.vn * 100)), int(round(s.ve * 100)), 0,
            int(round(f.heading * 100)) % 36000,
        )  # fmt: skip

    def _attitude(self, s: NavState, f: _Fix):  # type: ignore[no-untyped-def]
        yaw = math.radians(f.heading)
        if yaw > math.pi:
            yaw -= 2 * math.pi
        roll = math.radians(s.roll_deg) + self.rng.gauss(0.0, 0.02)
        pitch = self.rng.gauss(0.0, 0.02)
        return self.mav.attitude_encode(f.boot_ms, roll, pitch, yaw, 0.0, 0.0, s.yaw_rate)

    def _vfr_hud(self, s: NavState, f: _Fix):  # type: ignore[no-untyped-def]
        return self.mav.vfr_hud_encode(
            f.sog, f.sog, int(round(f.heading)) % 360, int(round(s.throttle * 100)), 0.0, 0.0
        )

    def _mission_current(self, s: NavState, f: _Fix):  # type: ignore[no-untyped-def]
        active = mavlink2.MISSION_STATE_ACTIVE if s.wp_total else mavlink2.MISSION_STATE_NO_MISSION
        return self.mav.mission_current_encode(s.wp_seq, s.wp_total, active, 0)

    def _nav_controller_output(self, s: NavState, f: _Fix):  # type: ignore[no-untyped-def]
        return self.mav.nav_controller_output_encode(
            0.0, 0.0, int(round(s.nav_bearing_deg)), int(round(s.target_bearing_deg)),
            min(int(round(s.wp_dist)), 65535), 0.0, 0.0, s.xtrack,
        )  # fmt: skip
