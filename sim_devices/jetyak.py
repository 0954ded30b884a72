"""The simulated boat's truth: a Mokai-based Jetyak's hull and its Rover autopilot's tuning.

The equations are `host.vessel`'s; these are the values the simulator flies with. The planner keeps its
own belief (`plan.boat_model`), which may be wrong.
"""

from __future__ import annotations

from forcemap.host.vessel.boat import BoatParams
from forcemap.host.vessel.control import Gains

# about 3.9 m and 180 kg with payload
JETYAK = BoatParams(
    m_surge=250.0,
    m_sway=380.0,
    inertia=220.0,
    x_u=10.0,
    x_uu=12.0,  # -> top speed ~5.5 m/s
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

# tuned on the lake at cruise speed, like a stock ArduPilot Rover
ROVER_GAINS = Gains(
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
