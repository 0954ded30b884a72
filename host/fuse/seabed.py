"""The seabed along the track: which soundings lie on one continuous bottom, when false echoes may
be the local majority.

A running median is the seabed as long as most soundings in its window are; where false echoes are
(a stretch of deep water where most soundings are 3-20 m: fish, a thermocline, wake), it follows
them, and the true bottom looks like deep spikes. What tells them apart is physics, not numbers: the
seabed is continuous along the track, false echoes are intermittent and scattered (each at its own
depth). So the seabed is found as the cheapest path through the soundings (dynamic programming, in
time order). A step from one sounding on the path to the next costs (change / tolerance) squared,
at most JUMP_COST (a real step of the bottom, a channel edge, costs that once); the tolerance is the
spike floor of the depth (0.5 m + 5 %), widened by SLOPE_SHARE (a quarter) for every sounding
skipped (the simulator's deep basin falls 1.2 m a sounding where the boat crosses its slope). A
sounding left off the path costs OFF_SHALLOW if it is above the path (shallower than both ends of
the step by more than the tolerance: what a false echo is) and OFF_DEEP otherwise (a path that runs
above soundings deeper than itself is above the seabed: echoes are never deeper than the bottom).
So a scattered echo is left off (a jump to it and one back cost more), a path along the echoes of a
stretch pays for every sounding of the bottom it leaves below it, and a plateau of 5 soundings or
more is followed (a sand bar, as a running median of 9 follows one wider than half its window); a
deep spike is left off, and a step down is followed at once.

The path does not flag anything: the spike test (forcemap.host.workbench.survey.spikes) takes its
reference from the soundings on it, and flags what departs from that by its threshold.
"""

from __future__ import annotations

import numpy as np

OFF_SHALLOW = 0.5  # a sounding left off the path above it: a false echo, or a bar not followed
OFF_DEEP = 1.5  # one left off below it or at its depth: the path would run above the seabed
JUMP_COST = 1.2  # a bar of 5 soundings is followed: 2 x JUMP_COST < 5 x OFF_SHALLOW
SLOPE_SHARE = 0.25
MAX_SKIP = 60  # soundings a step may jump over (at 60 % echoes, a run of 60 has odds 5e-14)
BLOCK = 256  # soundings whose step costs are formed at once (256 x 60 x 59 comparisons)


def seabed_path(depth: np.ndarray, tolerance: np.ndarray) -> np.ndarray:
    """True for the soundings on the cheapest continuous path (NaN soundings: False)."""
    n = len(depth)
    on = np.zeros(n, bool)
    idx = np.flatnonzero(np.isfinite(depth))
    if len(idx) < 3:
        on[idx] = True
        return on
    d, tol = depth[idx], np.maximum(tolerance[idx], 1e-9)
    m = len(d)
    best = np.empty(m)
    back = np.full(m, -1)
    lead = _ends(d, tol, np.arange(m) <= MAX_SKIP, before=True)
    for k0 in range(0, m, BLOCK):
        steps = _step_costs(d, tol, k0, min(m, k0 + BLOCK))
        for k in range(k0, min(m, k0 + BLOCK)):
            lo = k - MAX_SKIP if k > MAX_SKIP else 0
            best[k], back[k] = lead[k], -1
            if k == lo:
                continue
            cost = best[lo:k] + steps[k - k0, MAX_SKIP - (k - lo) :]
            i = cost.argmin()
            if cost[i] < best[k]:
                best[k], back[k] = cost[i], lo + i
    end = best + _ends(d, tol, np.arange(m) >= m - 1 - MAX_SKIP, before=False)
    k = int(np.argmin(end))
    while k >= 0:
        on[idx[k]] = True
        k = int(back[k])
    return on


def _step_costs(d: np.ndarray, tol: np.ndarray, k0: int, k1: int) -> np.ndarray:
    """For the soundings k0 .. k1 - 1 (rows) and the MAX_SKIP before each (columns, the nearest last), the cost of
    the step from that one to it plus the cost of the soundings skipped between them (inf before the first
    sounding): everything of the path's cost but the path so far, for a block of soundings at once."""
    k = np.arange(k0, k1)[:, None]
    j = k - MAX_SKIP + np.arange(MAX_SKIP)[None, :]
    valid = j >= 0
    j = np.maximum(j, 0)
    skipped = k - j - 1
    width = np.maximum(tol[j], tol[k]) * (1.0 + SLOPE_SHARE * skipped)
    step = np.minimum(((d[k] - d[j]) / width) ** 2, JUMP_COST)
    # the soundings between j and k (i = k - MAX_SKIP + 1 .. k - 1 by offset), above the path or not
    i = k - MAX_SKIP + 1 + np.arange(MAX_SKIP - 1)[None, :]
    between = d[np.maximum(i, 0)][:, None, :]
    inside = (i[:, None, :] > j[:, :, None]) & (i[:, None, :] >= 0)
    above = between < (np.minimum(d[j], d[k]) - width)[:, :, None]
    n_above = (inside & above).sum(axis=2)
    off = n_above * OFF_SHALLOW + (skipped - n_above) * OFF_DEEP
    return np.where(valid, off + step, np.inf)


def _ends(d: np.ndarray, tol: np.ndarray, may: np.ndarray, before: bool) -> np.ndarray:
    """The cost of starting (``before``) or ending the path at each sounding: every sounding
    before (after) it is off the path, above it or not; only within MAX_SKIP of the track's ends
    (``may``), elsewhere a path always has a sounding within reach."""
    out = np.full(len(d), np.inf)
    for k in np.flatnonzero(may):
        rest = d[:k] if before else d[k + 1 :]
        above = int((rest < d[k] - tol[k]).sum())
        out[k] = above * OFF_SHALLOW + (len(rest) - above) * OFF_DEEP
    return out


def reference_on(values: np.ndarray, window: int, running) -> np.ndarray:
    """The running median of the soundings on the path (``values``: NaN off it) over ``window``
    soundings along the track; where none of a window's is on it (a run of echoes), interpolated
    along the track from the nearest ones. Counted along the track, not along the path: where the
    path is sparse, ``window`` of its soundings span a valley and would cut its bottom off."""
    ref = running(values, window, np.nanmedian)
    known = np.flatnonzero(np.isfinite(ref))
    if not len(known):
        return ref
    gaps = np.flatnonzero(~np.isfinite(ref))
    ref[gaps] = np.interp(gaps, known, ref[known])
    return ref
