"""A 3-DOF surface vessel (surge, sway, yaw) like a Jetyak: jet thrust and nozzle, pushed by current and wind."""

from __future__ import annotations

import math
from dataclasses import dataclass

RHO_AIR = 1.2


@dataclass
class BoatParams:
    """Mokai-based Jetyak, about 3.9 m and 180 kg with payload; hydrodynamic terms are per SI unit."""

    m_surge: float = 250.0  # kg, mass plus added mass in surge
    m_sway: float = 380.0  # kg, mass plus added mass in sway
    inertia: float = 220.0  # kg m^2, yaw inertia plus added inertia
    x_u: float = 10.0  # N per m/s, linear surge drag
    x_uu: float = 12.0  # N per (m/s)^2, quadratic surge drag -> top speed ~5.5 m/s
    y_v: float = 120.0
    y_vv: float = 450.0
    n_r: float = 40.0  # N m per rad/s, yaw damping at rest
    n_ru: float = 40.0  # N m per rad/s per m/s, yaw damping growing with speed (hull and keel)
    n_rr: float = 60.0
    thrust_max: float = 420.0  # N
    nozzle_max_deg: float = 35.0  # jet nozzle deflection at full steering
    jet_arm: float = 1.8  # m from the jet to the centre of rotation
    area_front: float = 0.5  # m^2 above water
    area_side: float = 1.2
    cd_air: float = 0.9
    weathervane: float = (
        0.35  # m, lever of the side wind force about the centre (bow turns off the wind)
    )


@dataclass
class BoatState:
    """Position (m, local ENU), heading (compass rad), velocity through the water (body frame) and yaw rate."""

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

    def __init__(self, params: BoatParams | None = None, state: BoatState | None = None) -> None:
        self.p = params or BoatParams()
        self.s = state or BoatState()

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
