"""A replanned rest of the mission spliced into the one the autopilot holds, keeping what forcemap does
not move (issue 31).

The items before the first replaced one are kept as they are. After it, the planner's waypoints (with
its own DO_CHANGE_SPEED where it sets a leg's ground speed) replace the old waypoints of the remaining
lines and the turn points between them. Every other item of the replaced part (camera triggers, other
DO_ commands, the user's DO_CHANGE_SPEED) is kept unchanged, after the new waypoint that plays the part
of the old waypoint it followed: a line's first or last waypoint is that line's new first or last one,
another waypoint the nearest new one. Where the planner leaves a leg's speed to the mission, the speed
the user set for it still holds (the planner's items name it explicitly). The items after the last
line's end (a return leg, RTL) follow the new waypoints unchanged.
"""

from __future__ import annotations

import numpy as np
from forcemap.host.vessel import waypoints as wp

from .mission_io import nav_items


def _roles(line_seqs: list[tuple[int, int]]) -> dict[int, tuple[int, int]]:
    """seq -> (line, 0 for its first waypoint, 1 for its last)."""
    out: dict[int, tuple[int, int]] = {}
    for j, (a, b) in enumerate(line_seqs):
        out.setdefault(a, (j, 0))
        out[b] = (j, 1)
    return out


def splice(
    items: list[wp.Item],
    first_seq: int,
    line_seqs: list[tuple[int, int]],
    first_line: int,
    latlon: np.ndarray,
    speeds: np.ndarray,
    plan_lines: list[tuple[int, int]],
    cruise: float,
    old_overrun: int | None = None,
) -> tuple[list[wp.Item], list[int], list[tuple[int, int]]]:
    """The new mission (home first): ``items[:first_seq]``, then the planned waypoints ``latlon`` with
    leg ``speeds`` (NaN: the user's speed there, else ``cruise``) for the lines from ``first_line`` on
    (``plan_lines``: each one's first and last index in ``latlon``), with the replaced part's other
    items kept (``old_overrun``: the last line's overrun waypoint, which the plan's own replaces).
    Also the new waypoints' seqs and the new lines' (first, last) seqs."""
    old_ll, old_sp, old_seqs = nav_items(items)
    last_end = line_seqs[-1][1]
    tail_from = next(
        (s for s in range(max(first_seq, last_end + 1), len(items))
         if items[s].command == wp.NAV_WAYPOINT and s != old_overrun),
        len(items),
    )  # fmt: skip
    roles = _roles(line_seqs)
    user_speed = _user_speeds(old_sp, old_seqs, line_seqs, first_line, len(plan_lines))
    sp = np.array(speeds, dtype=float)
    for k, (_, b) in enumerate(plan_lines):  # line k's legs: into its run-in ... into its overrun
        lo = plan_lines[k - 1][1] + 2 if k else 0
        seg = sp[lo : b + 2]
        seg[~np.isfinite(seg)] = user_speed[k]
    sp[~np.isfinite(sp)] = cruise
    # the kept items, each after the index of the new waypoint it follows
    attach: dict[int, list[wp.Item]] = {}
    prev_nav: int | None = None
    floor = 0
    for s in range(first_seq, tail_from):
        it = items[s]
        if it.command == wp.NAV_WAYPOINT:
            prev_nav = s
            continue
        k = _anchor(prev_nav, roles, first_line, plan_lines, items, latlon, floor)
        floor = max(floor, k)
        attach.setdefault(k, []).append(it)
    part: list[wp.Item] = []
    new_seqs: list[int] = []
    last = float("nan")
    for i, (lat, lon) in enumerate(latlon):
        if i == 0 and -1 in attach:
            part += attach[-1]
        if not (np.isfinite(last) and abs(sp[i] - last) < 1e-6):
            part.append(wp.change_speed(float(sp[i])))
            last = float(sp[i])
        new_seqs.append(first_seq + len(part))
        part.append(wp.waypoint(float(lat), float(lon)))
        for it in attach.get(i, []):
            part.append(it)
            if it.command == wp.DO_CHANGE_SPEED and it.params[1] > 0:
                last = float("nan")  # the user's speed item changed it: name the next leg's again
    out = list(items[:first_seq]) + part + list(items[tail_from:])
    return out, new_seqs, [(new_seqs[a], new_seqs[b]) for a, b in plan_lines]


def _anchor(
    prev_nav: int | None,
    roles: dict[int, tuple[int, int]],
    first_line: int,
    plan_lines: list[tuple[int, int]],
    items: list[wp.Item],
    latlon: np.ndarray,
    floor: int,
) -> int:
    """The index of the new waypoint an item kept from the replaced part goes after (-1: before all)."""
    if prev_nav is None:
        return -1
    role = roles.get(prev_nav)
    if role is not None and role[0] >= first_line:
        return max(plan_lines[role[0] - first_line][role[1]], floor)
    it = items[prev_nav]
    d = np.hypot(latlon[:, 0] - it.lat, (latlon[:, 1] - it.lon) * np.cos(np.radians(it.lat)))
    return max(int(np.argmin(d)), floor)


def _user_speeds(
    old_sp: np.ndarray, old_seqs: np.ndarray, line_seqs: list[tuple[int, int]], first: int, n: int
) -> np.ndarray:
    """The ground speed the user's mission sets on each remaining line (NaN: none set)."""
    out = np.full(n, np.nan)
    for k in range(n):
        end = line_seqs[first + k][1]
        at = np.flatnonzero(old_seqs == end)
        if len(at):
            out[k] = old_sp[at[0]]
    return out
