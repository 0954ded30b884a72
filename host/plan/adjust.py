"""Adjust a waypoint mission so the boat holds its intended lines in the mapped current and wind.

What a waypoint autopilot can be given, and what each fixes:

- **order and direction against the flow**: the lines are flown in the order and direction whose
  first line runs most against the current;
- **speed per leg** (DO_CHANGE_SPEED): a Rover's speed loop holds *ground* speed, so with the flow it
  throttles back and a jet loses its steering. Each leg running with the current is given the ground
  speed that keeps the calm-water cruise speed through the water (capped below the boat's maximum);
- **approach and overrun waypoints**: each line gets a run-in on its own extension before it, so the
  boat has turned and settled before the line starts, and an overrun after it, so the next turn starts
  after the line ends;
- **turn points moved to pre-compensate drift**: each line is split into stretches; after predicting
  the track, each stretch's waypoints are moved against the predicted mean offset, and a line whose
  start is still missed gets a longer run-in. This repeats a few times.

The intended lines are kept unchanged beside the adjusted waypoints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .boat_model import BoatModel
from .maps import Maps
from .metrics import TOL_M
from .predict import Track, predict_track

APPROACH_M = 30.0
APPROACH_MAX_M = 90.0
OVERRUN_M = 12.0
STRETCH_M = 60.0
ITERATIONS = 4
CORNER_M = 1.0  # a line starting this close to where the last one ended continues from it
SETTLED_M = 0.25  # stop adjusting when no stretch would move more than this


@dataclass
class Plan:
    """A mission in local metres: waypoints, the ground speed into each (NaN: cruise), intended lines, and
    for each line the indices of the waypoints where it starts and ends."""

    wps: np.ndarray
    speeds: np.ndarray
    lines: np.ndarray  # (k, 2, 2)
    line_wps: list[tuple[int, int]]


def along_current(
    maps: Maps, a: np.ndarray, b: np.ndarray, scale: float = 1.0, t: float | None = None
) -> float:
    """Mean current component (m/s) along the segment a->b, from the map (at UNIX time `t`, if it changes
    in time)."""
    d = b - a
    length = float(np.hypot(*d)) or 1e-9
    pts = a + np.linspace(0.0, 1.0, max(int(length / 5.0), 2))[:, None] * d
    e, n, _ = maps.current.sample(pts, t)
    return scale * float(np.mean(e * d[0] + n * d[1]) / length)


def etas(wps: np.ndarray, boat: BoatModel, t_start: float | None) -> list[float | None]:
    """When the boat reaches each waypoint at cruise speed from UNIX time `t_start` (None: no time)."""
    if t_start is None:
        return [None] * len(wps)
    legs = np.r_[0.0, np.cumsum(np.hypot(*np.diff(wps, axis=0).T))]
    return list(t_start + legs / max(boat.cruise_speed, 0.5))


def leg_speed(
    maps: Maps, boat: BoatModel, a: np.ndarray, b: np.ndarray, t: float | None = None
) -> float:
    """Ground speed for a leg: cruise through the water when the flow helps (NaN: keep the cruise)."""
    c = along_current(maps, a, b, t=t)
    if c < 0.3:
        return float("nan")
    return round(min(boat.cruise_speed + c, 0.9 * boat.max_speed + c), 1)


def upstream_first(lines: np.ndarray, maps: Maps, t: float | None = None) -> np.ndarray:
    """The lines in an order and direction whose first line is flown most against the flow: as given,
    every line reversed, the order reversed, or both (each keeps a lawnmower's turns short); the given
    one unless another starts at least 0.2 m/s more against the current."""
    options = [lines, lines[:, ::-1], lines[::-1], lines[::-1, ::-1]]
    along = [along_current(maps, o[0, 0], o[0, 1], t=t) for o in options]
    best = int(np.argmin(along))
    return (options[best] if along[best] < along[0] - 0.2 else lines).copy()


def layout(
    lines: np.ndarray,
    approach: np.ndarray,
    shifts: list[np.ndarray],
    maps: Maps,
    boat: BoatModel,
    t_start: float | None = None,
) -> Plan:
    """Waypoints for the lines: run-in, the (shifted) line split into stretches, overrun; speeds per leg.
    Lines that share a waypoint with the one before (a corner, as every leg of a grid given as a line)
    are chained at it: no overrun before the corner, no run-in after it."""
    pts: list[np.ndarray] = []
    line_wps = []
    chained = [i > 0 and float(np.hypot(*(a - lines[i - 1][1]))) < CORNER_M
               for i, (a, _) in enumerate(lines)]  # fmt: skip
    for i, (a, b) in enumerate(lines):
        d = b - a
        length = float(np.hypot(*d))
        u = d / length
        n_st = len(shifts[i]) - 1
        on = [a + (k / n_st) * d + shifts[i][k] * np.array([u[1], -u[0]]) for k in range(n_st + 1)]
        if chained[i]:
            line_wps.append((len(pts) - 1, len(pts) - 1 + n_st))
            pts += on[1:]
        else:
            pts.append(on[0] - approach[i] * u)
            line_wps.append((len(pts), len(pts) + n_st))
            pts += on
        if i + 1 == len(lines) or not chained[i + 1]:
            pts.append(on[-1] + OVERRUN_M * u)
    wps = np.array(pts)
    speeds = np.full(len(wps), np.nan)
    when = etas(wps, boat, t_start)
    for k in range(1, len(wps)):
        speeds[k] = leg_speed(maps, boat, wps[k - 1], wps[k], when[k - 1])
    return Plan(wps, speeds, lines, line_wps)


def offsets_along(
    xy: np.ndarray, vel: np.ndarray, a: np.ndarray, b: np.ndarray, n_st: int
) -> np.ndarray:
    """Mean signed offset (m, right of the line positive) of the track's passes along a->b (positions
    ``xy``, steps ``vel``), at each stretch end."""
    d = b - a
    length = float(np.hypot(*d))
    u = d / length
    rel = xy - a
    along = rel @ u
    across = rel[:, 0] * u[1] - rel[:, 1] * u[0]
    on = (along >= 0) & (along <= length) & (np.abs(across) < 20.0) & (vel @ u > 0)
    out = np.zeros(n_st + 1)
    for k in range(n_st + 1):
        near = on & (np.abs(along - k * length / n_st) < 0.5 * length / n_st)
        if near.any():
            out[k] = float(np.mean(across[near]))
    return out


def start_missed(tree: cKDTree, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the first stretch of the line has a point with no track (``tree``) within the tolerance."""
    d = b - a
    u = d / float(np.hypot(*d))
    pts = a + np.linspace(0.0, min(30.0, float(np.hypot(*d))), 16)[:, None] * u
    return bool(np.any(tree.query(pts)[0] > 0.7 * TOL_M))


def from_start(plan: Plan, start: np.ndarray | None) -> Plan:
    """The plan flown from ``start`` (the boat's position) rather than from its first waypoint."""
    if start is None:
        return plan
    wps = np.vstack([np.asarray(start, dtype=float)[None, :], plan.wps])
    speeds = np.r_[np.nan, plan.speeds]
    return Plan(wps, speeds, plan.lines, [(a + 1, b + 1) for a, b in plan.line_wps])


def adjust(
    lines: np.ndarray,
    maps: Maps,
    boat: BoatModel,
    progress=None,  # type: ignore[no-untyped-def]
    start: np.ndarray | None = None,
    reorder: bool = True,
    t_start: float | None = None,
) -> tuple[Plan, Track]:
    """The adjusted plan for ``lines`` (in the order flown) and its predicted track; ``start``: flown
    from there (in flight), ``reorder=False``: in the order and directions given; from UNIX time
    ``t_start`` (default the maps' start): a current that changes in time is taken when the boat is there."""
    t_start = maps.start if t_start is None else t_start
    lines = np.asarray(lines, dtype=float)
    lines = upstream_first(lines, maps, t_start) if reorder else lines.copy()
    approach = np.full(len(lines), APPROACH_M)
    shifts = [np.zeros(max(int(round(np.hypot(*(b - a)) / STRETCH_M)), 1) + 1) for a, b in lines]
    plan = from_start(layout(lines, approach, shifts, maps, boat, t_start), start)
    track = predict_track(plan.wps, plan.speeds, maps, boat, t_start=t_start)
    for it in range(ITERATIONS):
        if progress is not None:
            progress(it + 1, ITERATIONS)
        moved = 0.0
        xy = track.xy
        tree, vel = cKDTree(xy), np.gradient(xy, axis=0)
        for i, (a, b) in enumerate(lines):
            off = offsets_along(xy, vel, a, b, len(shifts[i]) - 1)
            shifts[i] = shifts[i] - off
            moved = max(moved, float(np.abs(off).max()))
            if start_missed(tree, a, b) and approach[i] < APPROACH_MAX_M:
                approach[i] = min(approach[i] * 1.5, APPROACH_MAX_M)
                moved = np.inf
        if moved < SETTLED_M:
            break  # the last prediction already holds the lines: another pass would change nothing
        plan = from_start(layout(lines, approach, shifts, maps, boat, t_start), start)
        track = predict_track(plan.wps, plan.speeds, maps, boat, t_start=t_start)
    return plan, track


def original_plan(wps: np.ndarray, speeds: np.ndarray | None, lines: np.ndarray) -> Plan:
    """The mission as given, with its intended lines located among its legs."""
    line_wps = []
    for a, b in lines:
        ia = int(np.argmin(np.hypot(*(wps - a).T)))
        ib = int(np.argmin(np.hypot(*(wps - b).T)))
        line_wps.append((ia, ib))
    sp = np.full(len(wps), np.nan) if speeds is None else np.asarray(speeds, dtype=float)
    return Plan(np.asarray(wps, dtype=float), sp, np.asarray(lines, dtype=float), line_wps)
