"""What a replanned mission may not do (issue 22): move a waypoint more than a bound across its intended line
or out of the mission's area, or rest on a map with values no river or wind has."""

from __future__ import annotations

import numpy as np

from .maps import Field, Maps

BOUND_M = 30.0  # largest move of a waypoint across its intended line
MARGIN_M = 60.0  # the mission's area (its waypoints and lines) grown by this much
MAX_CURRENT_MPS = 8.0  # faster than any river a survey boat works in
MAX_WIND_MPS = 40.0


def map_problem(maps: Maps, area: tuple[float, float, float, float]) -> str | None:
    """Why a map cannot be trusted over ``area`` (x0, x1, y0, y1), or None."""
    for name, f, limit in (
        ("current", maps.current, MAX_CURRENT_MPS),
        ("wind", maps.wind, MAX_WIND_MPS),
    ):
        e, n = _in_area(f, area)
        if not (np.all(np.isfinite(e)) and np.all(np.isfinite(n))):
            return f"the {name} map has values that are not numbers"
        top = float(np.max(np.hypot(e, n))) if e.size else 0.0
        if top > limit:
            return f"the {name} map reaches {top:.1f} m/s (more than {limit:g} m/s)"
    return None


def _in_area(f: Field, area: tuple[float, float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    ny, nx = f.east.shape[-2:]  # a field in time: every slice
    gx = f.x0 + f.step * np.arange(nx)
    gy = f.y0 + f.step * np.arange(ny)
    cx = (gx >= area[0] - f.step) & (gx <= area[1] + f.step)
    cy = (gy >= area[2] - f.step) & (gy <= area[3] + f.step)
    if not cx.any() or not cy.any():  # a coarse grid (one cell over everything): all of it
        return f.east, f.north
    return f.east[..., cy, :][..., cx], f.north[..., cy, :][..., cx]


def owners(line_wps: list[tuple[int, int]], n: int) -> np.ndarray:
    """For each waypoint of a laid-out plan, the line it belongs to (run-in, on it, overrun); -1: none."""
    out = np.full(n, -1)
    for j, (a, b) in enumerate(line_wps):
        out[max(a - 1, 0) : min(b + 2, n)] = j
    return out


def clip(
    wps: np.ndarray, own: np.ndarray, lines: np.ndarray, bound_m: float, area: tuple
) -> tuple[np.ndarray, int, float]:
    """Waypoints moved back within ``bound_m`` across their line and into ``area``; how many moved, and
    the largest move (m)."""
    out = wps.copy()
    for k, j in enumerate(own):
        if j < 0:
            continue
        a, b = lines[j]
        u = (b - a) / np.hypot(*(b - a))
        nrm = np.array([u[1], -u[0]])
        off = float((out[k] - a) @ nrm)
        if abs(off) > bound_m:
            out[k] -= (off - np.sign(off) * bound_m) * nrm
    out[:, 0] = np.clip(out[:, 0], area[0], area[1])
    out[:, 1] = np.clip(out[:, 1], area[2], area[3])
    moved = np.hypot(*(out - wps).T)
    return out, int(np.sum(moved > 0.01)), float(moved.max()) if len(moved) else 0.0
