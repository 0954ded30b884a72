"""A 3-DOF surface vessel (surge, sway, yaw) like a Jetyak: jet thrust and nozzle, pushed by current and wind.

The equations only: the simulator's true hull is in `sim_devices.jetyak`, the planner's belief in
`plan.boat_model`; both are `BoatParams` values."""

from __future__ import annotations

import math
from dataclasses import dataclass

RHO_AIR = 1.2


@dataclass(frozen=True)
class BoatParams:
    """A jet-driven hull; hydrodynamic terms are per SI unit."""

    m_surge: float  # kg, mass plus added mass in surge
    m_sway: float  # kg, mass plus added mass in sway
    inertia: float  # kg m^2, yaw inertia plus added inertia
    x_u: float  # N per m/s, linear surge drag
    x_uu: float  # N per (m/s)^2, quadratic surge drag
    y_v: float  # N per m/s, linear sway drag
    y_vv: float  # N per (m/s)^2, quadratic sway drag
    n_r: float  # N m per rad/s, yaw damping at rest
    n_ru: float  # N m per rad/s per m/s, yaw damping growing with speed (hull and keel)
    n_rr: float  # N m per (rad/s)^2, quadratic yaw damping
    thrust_max: float  # N
    nozzle_max_deg: float  # jet nozzle deflection at full steering
    jet_arm: float  # m from the jet to the centre of rotation
    area_front: float  # m^2 above water
    area_side: float  # m^2 above water
    cd_air: float
    weathervane: float  # m, lever of the side wind force about the centre (bow turns off the wind)

    @property
    def max_speed(self) -> float:
        """Speed through the water at full throttle, straight ahead, from the hull's drag alone (m/s)."""
        return (-self.x_u + math.sqrt(self.x_u**2 + 4 * self.x_uu * self.thrust_max)) / (
            2 * self.x_uu
        )


@dataclass
class HullState:
    """The hull model's state: position (m, local ENU), heading (compass rad), velocity through the water
    (body frame), yaw rate, and velocity over ground."""

    x: float = 0.0
    y: float = 0.0
    psi: float = 0.0
    u: float = 0.0  # m/s forward through the water
    v: float = 0.0  # m/s to starboard through the water
    r: float = 0.0  # rad/s, clockwise positive
    ve: float = 0.0  # m/s over ground, east (updated each step)
    vn: float = 0.0


class Boat:
    """Integrates the vessel with semi-implicit Euler; the water's velocity enters through the kinematics."""

    def __init__(self, params: BoatParams, state: HullState | None = None) -> None:
        self.p = params
        self.s = state or HullState()

    def step(
        self,
        dt: float,
        throttle: float,
        steer: float,
        current: tuple[float, float],
        wind: tuple[float, float],
    ) -> None:
        """Advance by dt. throttle in [0, 1]; steer in [-1, 1], positive turns to starboard."""
        p, s = self.p, self.s
        sp, cp = math.sin(s.psi), math.cos(s.psi)
        # air velocity relative to the boat, in body axes
        rel_e, rel_n = wind[0] - s.ve, wind[1] - s.vn
        a_f = rel_e * sp + rel_n * cp
        a_s = rel_e * cp - rel_n * sp
        a_mag = math.hypot(a_f, a_s)
        fw_x = 0.5 * RHO_AIR * p.cd_air * p.area_front * a_mag * a_f
        fw_y = 0.5 * RHO_AIR * p.cd_air * p.area_side * a_mag * a_s
        thrust = p.thrust_max * min(max(throttle, 0.0), 1.0) ** 2  # a jet pump: thrust ~ rpm^2
        delta = math.radians(p.nozzle_max_deg) * min(max(steer, -1.0), 1.0)
        u, v, r = s.u, s.v, s.r
        du = (
            thrust * math.cos(delta) - p.x_u * u - p.x_uu * u * abs(u) + p.m_sway * v * r + fw_x
        ) / p.m_surge
        dv = (-p.y_v * v - p.y_vv * v * abs(v) - p.m_surge * u * r + fw_y) / p.m_sway
        n_damp = p.n_r + p.n_ru * abs(u)
        dr = (
            thrust * math.sin(delta) * p.jet_arm
            - n_damp * r
            - p.n_rr * r * abs(r)
            - p.weathervane * fw_y
        ) / p.inertia
        s.u = u + du * dt
        s.v = v + dv * dt
        s.r = r + dr * dt
        s.psi = (s.psi + s.r * dt) % (2.0 * math.pi)
        sp, cp = math.sin(s.psi), math.cos(s.psi)
        s.ve = s.u * sp + s.v * cp + current[0]
        s.vn = s.u * cp - s.v * sp + current[1]
        s.x += s.ve * dt
        s.y += s.vn * dt
