"""Predict the track a waypoint mission will fly through mapped current and wind, with the boat model.

The boat, its line-of-sight guidance and its heading and ground-speed loops are `host.vessel`'s (as the
simulator's), with the planner's belief about the boat (`boat_model`), run with
the mapped (not the true) current and wind at each point the boat reaches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from forcemap.host.vessel.boat import Boat, HullState
from forcemap.host.vessel.control import Controller, Navigator

from .boat_model import DT, BoatModel
from .maps import Maps

STUCK_S = 120.0  # no progress toward the waypoint for this long: the boat cannot make headway


@dataclass
class Track:
    """A predicted (or flown) track: times, positions, the leg flown (index of the waypoint ahead)."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    leg: np.ndarray
    throttle: np.ndarray
    stuck_at: int | None = None  # waypoint index the boat could not reach, if any

    @property
    def xy(self) -> np.ndarray:
        return np.column_stack([self.x, self.y])

    @property
    def duration(self) -> float:
        return float(self.t[-1]) if len(self.t) else 0.0


def predict_track(
    wps: np.ndarray,
    speeds: np.ndarray | None,
    maps: Maps,
    boat: BoatModel,
    current_scale: float = 1.0,
    t_max: float | None = None,
    t_start: float | None = None,
) -> Track:
    """Fly the waypoints once (no loop) from the first, heading for the second, as the simulator starts,
    from UNIX time `t_start` (default the maps' `start`): a current that changes in time is read at each
    step's time."""
    wps = np.asarray(wps, dtype=float)
    t_max = t_max if t_max is not None else longest_s(wps, boat)
    t_start = maps.start if t_start is None else t_start
    psi = math.atan2(wps[1, 0] - wps[0, 0], wps[1, 1] - wps[0, 1]) % (2 * math.pi)
    b = Boat(boat.hull, HullState(x=float(wps[0, 0]), y=float(wps[0, 1]), psi=psi, u=1.5))
    nav = Navigator(wps, boat.gains, loop=False, speeds=speeds)
    ctl = Controller(boat.cruise_speed, boat.gains)
    cur, wind = maps.current.at, maps.wind.at
    s = b.s
    step, nav_update, ctl_update, speed = b.step, nav.update, ctl.update, nav.speed
    hypot, cruise, radius = math.hypot, boat.cruise_speed, 2 * boat.gains.wp_radius_m
    end_x, end_y = float(wps[-1, 0]), float(wps[-1, 1])
    ts, xs, ys, legs, thr = [], [], [], [], []
    best, best_k, stuck, last_leg = math.inf, 0, None, nav.leg
    for k in range(int(t_max / DT)):
        psi_d, _ = nav_update(s.x, s.y)
        if nav.done and hypot(end_x - s.x, end_y - s.y) < radius:
            break
        ctl.cruise = speed(cruise)
        throttle, steer = ctl_update(DT, s.psi, s.r, psi_d, hypot(s.ve, s.vn))
        now = None if t_start is None else t_start + k * DT
        step(DT, throttle, steer, cur(s.x, s.y, current_scale, now), wind(s.x, s.y, 1.0, now))
        ts.append((k + 1) * DT)
        xs.append(s.x)
        ys.append(s.y)
        legs.append(nav.leg)
        thr.append(throttle)
        if k % 10:
            continue
        # headway: the distance to the waypoint ahead must keep falling
        if nav.leg != last_leg:
            last_leg, best, best_k = nav.leg, math.inf, k
        tx, ty = nav.target()
        d = hypot(tx - s.x, ty - s.y)
        if d < best - 1.0:
            best, best_k = d, k
        elif (k - best_k) * DT > STUCK_S:
            stuck = nav.leg
            break
    return Track(
        np.array(ts), np.array(xs), np.array(ys), np.array(legs, dtype=int), np.array(thr), stuck
    )


def longest_s(wps: np.ndarray, boat: BoatModel) -> float:
    """How long a prediction of `wps` may run before it is called stuck: 10 minutes plus three times the
    path at cruise speed (a field in time is gridded at least this far ahead)."""
    path = float(np.sum(np.hypot(*np.diff(np.asarray(wps, float), axis=0).T)))
    return 600.0 + 3.0 * path / max(boat.cruise_speed, 0.5)
