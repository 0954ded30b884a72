"""The boat and its autopilot as the planner believes them to be (the equations are `host.vessel`'s): by
default a Mokai-based Jetyak with a stock Rover tuning, summarised by cruise and maximum speed through the
water, turn rate and steering gains; a TOML overrides them.

    [boat]
    cruise_speed = 3.5       # m/s over ground, the autopilot's WP_SPEED
    max_speed = 5.5          # m/s through the water at full throttle (sets the jet's thrust)
    turn_rate_deg_s = 40     # deg/s at full steering and cruise speed in calm water (sets the jet's lever arm)
    [hull]                   # any field of vessel.boat.BoatParams
    [controller]             # any field of vessel.control.Gains (steer_kp, lookahead_m, wp_radius_m, ...)
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, fields, replace
from pathlib import Path

from forcemap.host.errors import CliError
from forcemap.host.vessel.boat import Boat, BoatParams, HullState
from forcemap.host.vessel.control import Gains

DT = 0.2  # s, the planner's step (the simulator's is 0.05 s)

# what the planner assumes without a boat file: the hull and tuning the simulator's boat was built from
HULL = BoatParams(
    m_surge=250.0,
    m_sway=380.0,
    inertia=220.0,
    x_u=10.0,
    x_uu=12.0,
    y_v=120.0,
    y_vv=450.0,
    n_r=40.0,
    n_ru=40.0,
    n_rr=60.0,
    thrust_max=420.0,
    nozzle_max_deg=35.0,
    jet_arm=1.8,
    area_front=0.5,
    area_side=1.2,
    cd_air=0.9,
    weathervane=0.35,
)
GAINS = Gains(
    steer_kp=2.5,
    steer_ki=0.05,
    steer_kd=1.0,
    speed_kp=0.25,
    speed_ki=0.05,
    throttle_ff=0.19,
    throttle_min=0.25,
    lookahead_m=10.0,
    wp_radius_m=3.0,
    turn_radius_m=4.5,
)


@dataclass
class BoatModel:
    cruise_speed: float = 3.5
    hull: BoatParams = HULL
    gains: Gains = GAINS

    @property
    def max_speed(self) -> float:
        """Speed through the water at full throttle, straight ahead (m/s)."""
        return self.hull.max_speed

    def turn_rate(self, speed: float | None = None) -> float:
        """Steady turn rate (deg/s) at full steering, starting at ``speed`` (default cruise) in calm water."""
        u = self.cruise_speed if speed is None else speed
        boat = Boat(self.hull, HullState(u=u))
        p = self.hull
        throttle = math.sqrt(min((p.x_u * u + p.x_uu * u * u) / p.thrust_max, 1.0))
        for _ in range(int(20.0 / 0.05)):
            boat.step(0.05, throttle, 1.0, (0.0, 0.0), (0.0, 0.0))
        return math.degrees(boat.s.r)

    def with_max_speed(self, v: float) -> BoatModel:
        p = self.hull
        return replace(self, hull=replace(p, thrust_max=p.x_u * v + p.x_uu * v * v))

    def with_turn_rate(self, deg_s: float) -> BoatModel:
        """The jet's lever arm scaled (secant steps) until the calm-water turn rate at cruise is ``deg_s``."""
        m = self
        arm0, r0 = m.hull.jet_arm, m.turn_rate()
        arm1 = arm0 * deg_s / max(r0, 1e-6)
        for _ in range(8):
            m = replace(m, hull=replace(m.hull, jet_arm=arm1))
            r1 = m.turn_rate()
            if abs(r1 - deg_s) < 0.05 or abs(r1 - r0) < 1e-9:
                break
            arm0, arm1, r0 = arm1, arm1 + (deg_s - r1) * (arm1 - arm0) / (r1 - r0), r1
        return m

    def describe(self) -> str:
        return (
            f"cruise {self.cruise_speed:.2f} m/s over ground, max {self.max_speed:.2f} m/s through water, "
            f"turn rate {self.turn_rate():.0f} deg/s, steering kp {self.gains.steer_kp:g} "
            f"kd {self.gains.steer_kd:g}, lookahead {self.gains.lookahead_m:g} m"
        )


def _override(obj, table: dict, where: str):  # type: ignore[no-untyped-def]
    names = {f.name for f in fields(obj)}
    bad = sorted(set(table) - names)
    if bad:
        raise CliError(
            f"{where}: unknown key(s) {', '.join(bad)}; known: {', '.join(sorted(names))}"
        )
    try:
        return replace(obj, **{k: float(v) for k, v in table.items()})
    except (TypeError, ValueError) as e:
        raise CliError(f"{where}: every value must be a number ({e})") from e


def load_boat(path: str | Path | None) -> BoatModel:
    """The planner's default boat, or one overridden by a TOML file."""
    m = BoatModel()
    if path is None:
        return m
    try:
        data = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise CliError(f"cannot read the boat file {path}: {e}") from e
    m = replace(
        m,
        hull=_override(m.hull, data.get("hull", {}), f"{path} [hull]"),
        gains=_override(m.gains, data.get("controller", {}), f"{path} [controller]"),
    )
    b = dict(data.get("boat", {}))
    unknown = sorted(set(b) - {"cruise_speed", "max_speed", "turn_rate_deg_s"})
    if unknown:
        raise CliError(f"{path} [boat]: unknown key(s) {', '.join(unknown)}")
    if "cruise_speed" in b:
        m = replace(m, cruise_speed=float(b["cruise_speed"]))
    if "max_speed" in b:
        m = m.with_max_speed(float(b["max_speed"]))
    if "turn_rate_deg_s" in b:
        m = m.with_turn_rate(float(b["turn_rate_deg_s"]))
    return m
