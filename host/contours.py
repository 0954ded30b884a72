"""Contour lines of a gridded scalar at round levels: the one home for `forcemap grid`'s GeoJSON
contours (host/gis, in UTM) and the live view's depth layer (host/live, in the survey's local frame).

Needs only contourpy and matplotlib (base dependencies), never the `gis` or `live` extras.
"""

from __future__ import annotations

import numpy as np

N_LEVELS = 10


def levels(values: np.ndarray, n: int = N_LEVELS) -> np.ndarray:
    """Round contour levels strictly inside the mapped range (matplotlib's tick rule)."""
    from matplotlib.ticker import MaxNLocator

    if not np.isfinite(values).any():
        return np.array([])
    lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
    if not hi > lo:
        return np.array([])
    ticks = MaxNLocator(n).tick_values(lo, hi)
    return ticks[(ticks > lo) & (ticks < hi)]


def contour_lines(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, n: int = N_LEVELS
) -> list[tuple[float, list[np.ndarray]]]:
    """(level, [line (k, 2) in x, y]) for each round level of ``z`` (ny, nx) on the axes ``x`` (nx)
    and ``y`` (ny); NaN cells are left out, lines of fewer than 2 points dropped."""
    import contourpy

    if z.shape[0] < 2 or z.shape[1] < 2:
        return []
    gen = contourpy.contour_generator(x, y, np.ma.masked_invalid(z))
    out = []
    for level in levels(z, n):
        lines = [line for line in gen.lines(float(level)) if len(line) >= 2]
        if lines:
            out.append((float(level), lines))
    return out
