"""Where the track crosses or revisits itself: pairs of readings close in space and apart in time.

One home for the import's depth checks (a beam angle from the crossings, a sounder against itself) and
the workbench's revisits (forcemap.host.workbench.depth.water_level): at a crossing two soundings measure one
bed, so their difference is the error of the soundings, not of the map.
"""

from __future__ import annotations

import numpy as np

MAX_PAIRS = (
    20_000  # a boat loitering over one spot gives pairs by the million: a seeded sample of them
)


def crossing_pairs(
    xy: np.ndarray, t: np.ndarray, radius_m: float, min_dt_s: float, max_pairs: int | None = None
) -> np.ndarray:
    """Pairs (i, j), i < j, of rows within ``radius_m`` of each other and at least ``min_dt_s`` apart
    (rows with a NaN position are never paired); at most ``max_pairs``, a seeded sample."""
    from scipy.spatial import cKDTree

    ok = np.flatnonzero(np.isfinite(xy).all(axis=1) & np.isfinite(t))
    if len(ok) < 2:
        return np.zeros((0, 2), int)
    pairs = ok[cKDTree(xy[ok]).query_pairs(radius_m, output_type="ndarray")]
    pairs = pairs[np.abs(t[pairs[:, 0]] - t[pairs[:, 1]]) >= min_dt_s]
    if max_pairs is not None and len(pairs) > max_pairs:
        keep = np.random.default_rng(0).choice(len(pairs), max_pairs, replace=False)
        pairs = pairs[np.sort(keep)]
    return pairs
