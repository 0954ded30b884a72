"""How well a track holds the intended survey lines: distance from each line, coverage, time on it.

For each intended line (a segment from start to end):

- ``p95``: the 95th percentile of the track's distance from the line while the boat flies along it (track
  points whose projection falls on the segment, moving along its direction, within ``window`` of it);
- ``miss``: the largest such distance;
- ``coverage``: the share of the line's length (sampled every 0.5 m) with a track point within ``tol``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

TOL_M = 3.0


@dataclass
class LineScore:
    line: int
    length: float
    p95: float
    miss: float
    coverage: float
    time_s: float  # time spent flying along the line

    def to_json(self) -> dict:
        return {k: (round(v, 3) if isinstance(v, float) else v) for k, v in asdict(self).items()}


def same_direction_window(lines: np.ndarray, default: float = 25.0) -> float:
    """Half the smallest distance between two parallel lines flown the same way (the pass of one line
    must not be taken for another's), at most ``default``."""
    mids = lines.mean(axis=1)
    dirs = lines[:, 1] - lines[:, 0]
    dirs = dirs / np.maximum(np.linalg.norm(dirs, axis=1, keepdims=True), 1e-9)
    best = 2 * default
    for i in range(len(lines)):
        for j in range(i + 1, len(lines)):
            if dirs[i] @ dirs[j] > 0.7:
                d = mids[j] - mids[i]
                across = abs(-d[0] * dirs[i, 1] + d[1] * dirs[i, 0])
                best = min(best, across) if across > 1.0 else best
    return min(default, 0.9 * best)


def score_lines(
    t: np.ndarray, xy: np.ndarray, lines: np.ndarray, tol: float = TOL_M
) -> list[LineScore]:
    """Scores of a track (times ``t``, positions ``xy``) against every intended line."""
    window = same_direction_window(lines)
    tree = cKDTree(xy) if len(xy) else None
    vel = np.gradient(xy, axis=0) if len(xy) > 1 else np.zeros_like(xy)
    slow = 0.3 * np.maximum(np.hypot(vel[:, 0], vel[:, 1]), 1e-9)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.1
    out = []
    for i, (a, b) in enumerate(lines):
        d = b - a
        length = float(np.hypot(*d))
        u = d / max(length, 1e-9)
        rel = xy - a
        along = rel @ u
        across = np.abs(rel[:, 0] * u[1] - rel[:, 1] * u[0])
        moving = vel @ u > slow
        on = (along >= 0) & (along <= length) & (across < window) & moving
        pts = a + np.linspace(0.0, 1.0, max(int(length / 0.5), 2))[:, None] * d
        near = tree.query(pts)[0] if tree is not None else np.full(len(pts), np.inf)
        out.append(
            LineScore(
                i,
                length,
                float(np.percentile(across[on], 95)) if on.any() else float("inf"),
                float(across[on].max()) if on.any() else float("inf"),
                float(np.mean(near <= tol)),
                float(on.sum() * dt),
            )
        )
    return out


def summary(scores: list[LineScore]) -> dict:
    """Length-weighted over all lines: p95 of the worst line, overall coverage, largest miss."""
    w = np.array([s.length for s in scores])
    return {
        "p95_worst_line": max(s.p95 for s in scores),
        "miss": max(s.miss for s in scores),
        "coverage": float(np.sum(w * [s.coverage for s in scores]) / w.sum()),
    }


def distance_to_path(xy: np.ndarray, wps: np.ndarray) -> np.ndarray:
    """Distance from each point to the polyline through ``wps``."""
    a, b = wps[:-1], wps[1:]
    d = b - a
    p = xy[:, None, :]
    u = np.clip(np.sum((p - a) * d, axis=2) / np.maximum(np.sum(d * d, axis=1), 1e-9), 0.0, 1.0)
    return np.min(np.linalg.norm(p - (a + u[..., None] * d), axis=2), axis=1)


def stretches(flags: np.ndarray, s: np.ndarray) -> list[tuple[float, float]]:
    """(from, to) of each run of True in ``flags`` along positions ``s``."""
    runs, start = [], None
    for si, flag in zip(s, flags, strict=True):
        if flag and start is None:
            start = si
        if not flag and start is not None:
            runs.append((round(float(start), 1), round(float(si), 1)))
            start = None
    if start is not None:
        runs.append((round(float(start), 1), round(float(s[-1]), 1)))
    return runs


def missed_stretches(
    xy: np.ndarray, lines: np.ndarray, tol: float = TOL_M
) -> list[list[tuple[float, float]]]:
    """Per line, the stretches (m along it) with no track point within ``tol``."""
    tree = cKDTree(xy)
    out = []
    for a, b in lines:
        length = float(np.hypot(*(b - a)))
        s = np.linspace(0.0, length, max(int(length / 0.5), 2))
        near = tree.query(a + (s / length)[:, None] * (b - a))[0]
        out.append(stretches(near > tol, s))
    return out
