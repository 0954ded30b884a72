"""Where the boat is on its intended lines: which mission items each line runs between, in the order and
direction the mission flies them, and when a line ends and the turn after it ends (issue 31).

A line ends when the boat's position, projected on the line, reaches its end (less ``END_M``) or when
MISSION_CURRENT moves past the line's end waypoint (the start of the turn); the turn after it ends when
the boat has gone for the item after the next line's first waypoint and is ``ON_NEXT_M`` along that line.
Neither depends on the next line having its own first waypoint: lines that share a waypoint (Mission
Planner's and QGC's survey grids), lead-in and overshoot points, and lines flown against the direction
they were given in all work alike.
"""

from __future__ import annotations

import numpy as np

END_M = 2.0  # a line has ended this close to its end, along it
ON_NEXT_M = 10.0  # the turn is over once the boat is this far along the next line
ON_LINE_M = 30.0  # farther than this across a line, the boat is not flying it
MATCH_M = 1.0  # a waypoint this close to a line's end is that end


def along_across(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    """(distance along a->b from a, distance across it (right positive), the line's length)."""
    d = b - a
    length = float(np.hypot(*d)) or 1e-9
    u = d / length
    r = np.asarray(p, dtype=float) - a
    return float(r @ u), float(r[0] * u[1] - r[1] * u[0]), length


def _nearest(xy: np.ndarray, p: np.ndarray, after: int) -> int:
    """Index of the waypoint at ``p``: the first within MATCH_M at or after ``after`` if there is one
    (a point visited twice belongs to the later pass), else the nearest."""
    dist = np.hypot(*(xy - p).T)
    close = np.flatnonzero(dist <= MATCH_M)
    later = close[close >= after]
    if len(later):
        return int(later[0])
    return int(close[0]) if len(close) else int(np.argmin(dist))


def match_lines(
    lines: np.ndarray, xy: np.ndarray, seqs: np.ndarray
) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """The intended lines oriented as flown and in the order flown, and each one's (first, last) mission
    item: the waypoints at its ends (``xy`` the mission's waypoints, ``seqs`` their item numbers)."""
    found = []
    cursor = 0
    for a, b in np.asarray(lines, dtype=float):
        ia = _nearest(xy, a, cursor)
        ib = _nearest(xy, b, cursor)
        if ia > ib:  # the mission flies it from b to a
            a, b, ia, ib = b, a, ib, ia
        if ia == ib:  # a degenerate match: take the next waypoint as its end
            ib = min(ia + 1, len(xy) - 1)
        found.append((ia, ib, a, b))
        cursor = ib
    found.sort(key=lambda f: (f[0], f[1]))
    out = np.array([[a, b] for _, _, a, b in found], dtype=float).reshape(-1, 2, 2)
    return out, [(int(seqs[ia]), int(seqs[ib])) for ia, ib, _, _ in found]


def line_ended(
    pos: np.ndarray | None, current: int | None, line: np.ndarray, seqs: tuple[int, int]
) -> bool:
    """Whether the boat has finished this line: MISSION_CURRENT past its last item, or its position at
    the line's end (and near the line)."""
    if current is not None and current > seqs[1]:
        return True
    if pos is None or current is None or current < seqs[0]:
        return False
    along, across, length = along_across(pos, *line)
    return along >= length - END_M and abs(across) < ON_LINE_M


def turn_over(
    pos: np.ndarray | None, current: int | None, line: np.ndarray, seqs: tuple[int, int]
) -> bool:
    """Whether the boat is already flying this (the next) line: it has gone for an item after the line's
    first one and is ON_NEXT_M along it, or has finished it."""
    if current is None or current <= seqs[0]:
        return False
    if current > seqs[1] or pos is None:
        return current > seqs[1]
    along, across, _ = along_across(pos, *line)
    return along >= ON_NEXT_M and abs(across) < ON_LINE_M


def to_go(
    pos: np.ndarray | None, current: int | None, line: np.ndarray, seqs: tuple[int, int]
) -> float:
    """Metres left on the line (inf when the boat is not flying it yet, or not near it)."""
    if pos is None or current is None or not seqs[0] < current <= seqs[1]:
        return float("inf")
    along, across, length = along_across(pos, *line)
    return length - along if abs(across) < ON_LINE_M and along > 0 else float("inf")
