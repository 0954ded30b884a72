"""Waypoint guidance and PID heading and speed control, like a stock ArduPilot Rover's AUTO mode.

The laws only: the simulated autopilot's tuning is in `sim_devices.jetyak`, the planner's belief in
`plan.boat_model`; both are `Gains` values."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from forcemap.host.vessel.geodesy import wrap_from_minus_pi


@dataclass
class PID:
    kp: float
    ki: float
    kd: float
    i_limit: float
    integral: float = 0.0

    def update(self, error: float, rate: float, dt: float) -> float:
        """PID output; ``rate`` is the measured rate of the controlled variable (derivative on measurement)."""
        self.integral = min(max(self.integral + self.ki * error * dt, -self.i_limit), self.i_limit)
        return self.kp * error + self.integral - self.kd * rate


@dataclass(frozen=True)
class Gains:
    """An autopilot's tuning; nothing here knows about current."""

    steer_kp: float  # per rad of heading error
    steer_ki: float  # per rad s of heading error
    steer_kd: float  # per rad/s of yaw rate
    speed_kp: float  # throttle per m/s of ground-speed error
    speed_ki: float  # throttle per m of ground-speed error
    throttle_ff: float  # throttle per m/s of target speed (calm-water cruise feed-forward)
    throttle_min: float  # MOT_THR_MIN: keep some jet flow for steering
    lookahead_m: float  # line-of-sight guidance
    wp_radius_m: float  # a waypoint is reached this close
    turn_radius_m: float  # calm-water turning radius at cruise, for turning before a waypoint


class Navigator:
    """Follows a waypoint list leg by leg with line-of-sight guidance, like ArduPilot's AUTO mode."""

    def __init__(
        self,
        waypoints: np.ndarray,
        gains: Gains,
        loop: bool = True,
        speeds: np.ndarray | None = None,
    ) -> None:
        self.wps = np.asarray(waypoints, dtype=float)
        self.loop = loop
        # ground speed on the leg into each waypoint (DO_CHANGE_SPEED), NaN: the cruise speed
        self.speeds = None if speeds is None else np.asarray(speeds, dtype=float)
        self.g = gains
        self.leg = 1  # heading from wps[leg-1] to wps[leg]
        self.legs_done = 0
        self.done = False
        self._legs: dict[int, tuple[float, ...]] = {}

    def _advance(self) -> None:
        self.legs_done += 1
        self.leg += 1
        if self.leg >= len(self.wps):
            if not self.loop:
                self.done = True
                self.leg = len(self.wps) - 1
                return
            self.wps = self.wps[::-1].copy()  # survey the pattern again in reverse
            self.speeds = None
            self._legs = {}
            self.leg = 1

    def speed(self, cruise: float) -> float:
        """The ground speed commanded on the current leg."""
        if self.speeds is None:
            return cruise
        s = float(self.speeds[self.leg])
        return s if math.isfinite(s) and s > 0 else cruise

    def _switch_distance(self, tx: float, ty: float) -> float:
        """How far before a waypoint to start the turn onto the next leg (calm-water turn anticipation)."""
        nxt = self.wps[self.leg + 1] if self.leg + 1 < len(self.wps) else self.wps[self.leg - 1]
        b = self.wps[self.leg]
        n = math.hypot(nxt[0] - b[0], nxt[1] - b[1]) or 1e-9
        turn = math.acos(max(-1.0, min(1.0, ((nxt[0] - b[0]) * tx + (nxt[1] - b[1]) * ty) / n)))
        return max(
            self.g.wp_radius_m, self.g.turn_radius_m * math.tan(min(turn, math.radians(120)) / 2)
        )

    def _geometry(self) -> tuple[float, float, float, float, float, float, float]:
        """(ax, ay, bx, by, unit tx, ty, length) of the current leg, and its turn-switch distance (cached)."""
        g = self._legs.get(self.leg)
        if g is None:
            a, b = self.wps[self.leg - 1], self.wps[self.leg]
            dx, dy = float(b[0] - a[0]), float(b[1] - a[1])
            length = math.hypot(dx, dy) or 1e-9
            tx, ty = dx / length, dy / length
            g = (float(a[0]), float(a[1]), float(b[0]), float(b[1]), tx, ty, length)
            g = (*g, self._switch_distance(tx, ty))
            self._legs[self.leg] = g
        return g

    def target(self) -> tuple[float, float]:
        """The waypoint ahead (x, y)."""
        g = self._geometry()
        return g[2], g[3]

    def update(self, x: float, y: float) -> tuple[float, float]:
        """Desired heading (compass rad) and signed cross-track error (m, right of track positive)."""
        for _ in range(len(self.wps)):
            ax, ay, bx, by, tx, ty, length, early = self._geometry()
            along = (x - ax) * tx + (y - ay) * ty
            if self.done or (
                length - along > early and math.hypot(bx - x, by - y) > self.g.wp_radius_m
            ):
                break
            self._advance()
        xte = -(x - ax) * ty + (y - ay) * tx  # left of track positive here
        bearing = math.atan2(tx, ty)
        return (bearing + math.atan2(xte, self.g.lookahead_m)) % (2 * math.pi), -xte


class Controller:
    """Heading PID on the nozzle, speed PID on GPS ground speed (as ArduPilot does) on the throttle."""

    def __init__(self, cruise_speed: float, gains: Gains) -> None:
        self.g = gains
        self.cruise = cruise_speed
        self.heading = PID(self.g.steer_kp, self.g.steer_ki, self.g.steer_kd, 0.3)
        self.speed = PID(self.g.speed_kp, self.g.speed_ki, 0.0, 0.4)

    def update(
        self, dt: float, psi: float, r: float, psi_target: float, sog: float
    ) -> tuple[float, float]:
        """(throttle 0..1, steer -1..1) for the measured heading, yaw rate and ground speed."""
        steer = self.heading.update(wrap_from_minus_pi(psi_target - psi), r, dt)
        throttle = self.g.throttle_ff * self.cruise + self.speed.update(self.cruise - sog, 0.0, dt)
        return min(max(throttle, self.g.throttle_min), 1.0), min(max(steer, -1.0), 1.0)
