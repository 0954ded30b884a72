"""The bottom lost: stretches where the soundings scatter more than a seabed can, so no bottom lies under them.

In deep water and a rough sea a single-beam sounder loses the bottom for minutes: its returns scatter
from a few metres to most of the depth from one ping to the next (fish, a thermocline, aeration under
the hull, the pulse's side lobes). False echoes among a bottom that is still there leave a continuous
seabed under them, however many they are (forcemap.host.fuse.seabed finds its path); a lost
bottom does not, and the path drawn through its scatter is jagged. Two shares, along the track in a
window of WINDOW soundings, say which:

- the path's own continuity: each sounding on the path lies within NEAR_M + NEAR_SHARE x depth of the
  straight line between the path's soundings before and after it. Near 1 on any bottom, with 60 % or
  80 % false echoes or a rough sea's heave; about 0.2 through scatter from 3 to 70 m;
- the soundings on the bottom: each sounding lies that close to the line between the *other* path
  soundings nearest before and after it (a sounding is never its own evidence). Near 1 on a clean
  bottom, 0.4 where six soundings in ten are false echoes, 0.2 at eight in ten, about 0.05 in scatter.

Where both are low (under PATH_SHARE and LOST_SHARE), and the soundings jump from ping to ping (their
median change over the window above SCATTER_M + SCATTER_SHARE x their median: 19 m in scatter from 3 to
70 m, decimetres on a steep shallow bottom whose curves the straight lines miss) for at least
MIN_SOUNDINGS soundings, the bottom is lost: the stretch runs out on either side to where the bottom is back (RESUME soundings in a row on
it, or continuing their neighbours within the tolerance and a steep seabed's STEP_M), every sounding
in it is flagged (one that lands near a path drawn through scatter is a coincidence, not the bottom),
left out of the depth map, and the stretch is listed with its times.

Two more signatures (issue 37, docs/SOUNDINGS.md): a run of at least MIN_SOUNDINGS soundings between
two returns of the bottom with almost none on it (a deep patch crossed in a minute, too short for the
windows); and, where the positions are known, a seabed path that climbs and falls faster than
MAX_SLOPE against the distance travelled, both ways, by more than REVERSAL_SHARE of that distance in a
window (a damped sounder gliding between its shallowest and deepest readings, every step continuous).

One home for the import (forcemap.host.convert.depth_findings: a ``qa.depth.bottom_lost`` finding and the
rows marked ``bottom_lost``) and the workbench (forcemap.host.workbench.survey.spikes: the rows left out of the
depth map): ``depth_lost`` runs the whole test on a column of soundings.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from forcemap.host.fuse.seabed import seabed_path

WINDOW = 61
PATH_SHARE = 0.5
LOST_SHARE = 0.2
SCATTER_M = 2.0  # the median change between pings in a window where the bottom is lost, at least
SCATTER_SHARE = 0.1  # ... plus this share of the soundings' median
STEP_M = 1.5  # the steepest step between two pings followed (the simulator's basin: 1.2 m)
MIN_SOUNDINGS = 30
NEAR_M = 0.3
NEAR_SHARE = 0.01
RESUME = 3
# the steepest seabed followed from one sounding to the next: 1 in 2 (27 deg) against the distance
# travelled, beyond the spike floor
MAX_SLOPE = 0.5
# a window where the path climbs and falls faster than that, both ways, by more than this share of the
# distance travelled (and each way beyond the floor) has no seabed under it
REVERSAL_SHARE = 0.1
# rows are grouped into readings when at least this share repeats the row before (the simulator's
# 4 rows per 1-Hz sounding: 75 %)
HELD_SHARE = 0.7
# the seabed path's tolerance: the spike floor of a sounding (0.5 m + 5 % of the depth)
PATH_FLOOR_M = 0.5
PATH_FLOOR_SHARE = 0.05


@dataclass
class LostStretch:
    """One stretch where the bottom was lost: soundings ``i0`` to ``i1`` (inclusive, by reading)."""

    i0: int
    i1: int
    t0: float  # seconds since the survey's start
    t1: float
    share: float  # the share of its soundings on a seabed
    why: str = "scatter"  # "scatter" (no seabed under the soundings), "steep" (one no seabed can be)

    @property
    def n(self) -> int:
        return self.i1 - self.i0 + 1

    def text(self) -> str:
        how = {
            "scatter": f"{self.share:.0%} on a seabed",
            "steep": "climbing and falling faster than a seabed",
        }
        evidence = "; ".join(how.get(w, w) for w in self.why.split("+"))
        return f"{self.t0 / 60:.1f}-{self.t1 / 60:.1f} min ({self.n} soundings, {evidence})"


def _tolerance(depth: np.ndarray) -> np.ndarray:
    return NEAR_M + NEAR_SHARE * np.abs(depth)


def _line(p: np.ndarray, depth: np.ndarray, i: np.ndarray) -> np.ndarray:
    """The straight line between the path soundings ``p`` nearest before and after each ``i``
    (excluding ``i`` itself); the nearest one where there is none on one side."""
    after = np.searchsorted(p, i, side="right")
    before = np.searchsorted(p, i, side="left") - 1
    j = p[np.clip(before, 0, len(p) - 1)]
    k = p[np.clip(after, 0, len(p) - 1)]
    j = np.where(before < 0, k, j)
    k = np.where(after >= len(p), j, k)
    w = np.where(k > j, (i - j) / np.maximum(k - j, 1), 0.0)
    return depth[j] + w * (depth[k] - depth[j])


def on_bottom(depth: np.ndarray, on_path: np.ndarray) -> np.ndarray:
    """Each sounding near the line between the other path soundings before and after it."""
    p = np.flatnonzero(on_path & np.isfinite(depth))
    if len(p) < 2:
        return np.zeros(len(depth), bool)
    ref = _line(p, depth, np.arange(len(depth)))
    return np.abs(depth - ref) <= _tolerance(ref)


def path_continuity(depth: np.ndarray, on_path: np.ndarray) -> np.ndarray:
    """1 for a path sounding near the line between its path neighbours, 0 if not, NaN off the path."""
    out = np.full(len(depth), np.nan)
    p = np.flatnonzero(on_path & np.isfinite(depth))
    if len(p) < 3:
        return out
    ref = _line(p, depth, p[1:-1])
    out[p[1:-1]] = np.abs(depth[p[1:-1]] - ref) <= _tolerance(ref)
    return out


def _continues(depth: np.ndarray) -> np.ndarray:
    """Each sounding within the tolerance and STEP_M of the sounding before or after it."""
    step = np.abs(np.diff(depth)) <= _tolerance(depth[1:]) + STEP_M
    out = np.zeros(len(depth), bool)
    out[1:] |= step
    out[:-1] |= step
    return out


def lost_stretches(
    depth: np.ndarray,
    on_path: np.ndarray,
    trel: np.ndarray,
    running: Callable,
    step_m: np.ndarray | None = None,
) -> list[LostStretch]:
    """The stretches (by reading) where the bottom was lost; ``on_path``: the soundings on the
    seabed's path (seabed.py), ``trel`` each reading's time, ``running`` the along-track window,
    ``step_m`` the distance travelled since the reading before (None: not known, so the steepness
    test is not made). Readings without a sounding (NaN) are left out: the windows count soundings."""
    idx = np.flatnonzero(np.isfinite(depth))
    if len(idx) < MIN_SOUNDINGS:
        return []
    step = None
    if step_m is not None:  # the distance between the soundings kept, across the NaN rows
        step = np.diff(np.r_[0.0, np.nancumsum(np.nan_to_num(step_m))[idx]])
    found = _stretches(depth[idx], on_path[idx], trel[idx], running, step)
    return [
        LostStretch(int(idx[s.i0]), int(idx[s.i1]), s.t0, s.t1, s.share, s.why) for s in found
    ]


def _scatter_spans(
    depth: np.ndarray, on_path: np.ndarray, bottom: np.ndarray, running: Callable
) -> list[list[int]]:
    """Where the soundings scatter with no seabed under them (their shares low, their jumps big)."""
    share = running(bottom.astype(float), WINDOW, np.nanmean)
    path = running(path_continuity(depth, on_path), WINDOW, np.nanmean)
    low = (np.nan_to_num(share, nan=1.0) < LOST_SHARE) & (np.nan_to_num(path, nan=1.0) < PATH_SHARE)
    # and the soundings jump, from ping to ping, by metres and a share of the depth
    jump = running(np.abs(np.diff(depth, prepend=depth[0])), WINDOW, np.nanmedian)
    low &= jump > SCATTER_M + SCATTER_SHARE * running(depth, WINDOW, np.nanmedian)
    near = bottom | _continues(depth)  # at the stretch's ends, the bottom on one side only
    # the bottom is back where RESUME soundings in a row are on it
    back = np.convolve(near.astype(int), np.ones(RESUME, int), "same") >= RESUME
    spans: list[list[int]] = []
    edges = np.flatnonzero(np.diff(np.r_[0, low.astype(int), 0]))
    for a, b in zip(edges[::2], edges[1::2] - 1, strict=True):
        # the window is wide: its share dips only well inside a stretch; the stretch runs out to
        # where the bottom is back on either side
        while a > 0 and not back[a - 1]:
            a -= 1
        while b < len(depth) - 1 and not back[b + 1]:
            b += 1
        while a < b and near[a]:  # the last sounding of the bottom before it is not in it
            a += 1
        while b > a and near[b]:
            b -= 1
        spans.append([int(a), int(b)])
    return spans


def _bridged_spans(
    depth: np.ndarray, on_path: np.ndarray, bottom: np.ndarray
) -> list[list[int]]:
    """Runs of at least MIN_SOUNDINGS soundings between two returns of the bottom (RESUME on it in a
    row) where almost none is on it (under half LOST_SHARE) and they jump from ping to ping by more
    than SCATTER_M + SCATTER_SHARE x the bed's depth: a stretch too short for the windows (the boat
    crossing a deep patch past the sounder's range in a minute). False echoes never do it: they leave
    the bottom under a share of the pings, and jump among themselves by metres in deep water."""
    p = np.flatnonzero(on_path & np.isfinite(depth))
    if len(p) < 2:
        return []
    bed = np.interp(np.arange(len(depth)), p, depth[p])
    back = np.convolve(bottom.astype(int), np.ones(RESUME, int), "same") >= RESUME
    near = bottom | _continues(depth)  # the last sounding of the bottom before it is not in it
    spans = []
    edges = np.flatnonzero(np.diff(np.r_[0, (~back).astype(int), 0]))
    for a, b in zip(edges[::2], edges[1::2] - 1, strict=True):
        while a < b and near[a]:
            a += 1
        while b > a and near[b]:
            b -= 1
        if b - a + 1 < MIN_SOUNDINGS or np.mean(bottom[a : b + 1]) >= 0.5 * LOST_SHARE:
            continue
        jump = float(np.median(np.abs(np.diff(depth[a : b + 1]))))
        if jump > SCATTER_M + SCATTER_SHARE * float(np.median(bed[a : b + 1])):
            spans.append([int(a), int(b)])
    return spans


def impossible_steps(depth: np.ndarray, on_path: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Per reading, how far (m) the seabed's path climbs (+) or falls (-) into it beyond what a seabed
    can between the two soundings: the spike floor, plus MAX_SLOPE x the distance travelled."""
    p = np.flatnonzero(on_path & np.isfinite(depth))
    if len(p) < 2:
        return np.zeros(len(depth))
    bed = np.interp(np.arange(len(depth)), p, depth[p])
    change = np.diff(bed, prepend=bed[0])
    allowed = path_tolerance(bed) + MAX_SLOPE * np.nan_to_num(step)
    return np.sign(change) * np.maximum(np.abs(change) - allowed, 0.0)


def _steep_spans(
    depth: np.ndarray, on_path: np.ndarray, step: np.ndarray, running: Callable
) -> list[list[int]]:
    """Where the seabed's path climbs and falls, both ways, by more than REVERSAL_SHARE of the distance
    travelled: a damped sounder that has lost the bottom glides from its shallowest reading to its
    deepest and back (1.8 to 108 m and back within 37 m of travel), every step continuous, none of it
    a seabed. A steep wall climbs or falls one way; sand bars and heave stay inside the floor."""
    imp = impossible_steps(depth, on_path, step)
    up = running(np.maximum(imp, 0.0), WINDOW, np.nansum)
    down = running(np.maximum(-imp, 0.0), WINDOW, np.nansum)
    travelled = running(np.nan_to_num(step), WINDOW, np.nansum)
    floor = path_tolerance(running(depth, WINDOW, np.nanmedian))
    turn = np.minimum(up, down)
    steep = (turn > floor) & (2.0 * turn > REVERSAL_SHARE * travelled)
    spans: list[list[int]] = []
    edges = np.flatnonzero(np.diff(np.r_[0, steep.astype(int), 0]))
    jumps = np.flatnonzero(imp)
    for a, b in zip(edges[::2], edges[1::2] - 1, strict=True):
        # from the first step beyond the floor the windows saw to the last
        inside = jumps[(jumps >= a - WINDOW // 2) & (jumps <= b + WINDOW // 2)]
        if len(inside):
            spans.append([int(inside[0]), int(inside[-1])])
    return spans


def _stretches(
    depth: np.ndarray,
    on_path: np.ndarray,
    trel: np.ndarray,
    running: Callable,
    step: np.ndarray | None,
) -> list[LostStretch]:
    bottom = on_bottom(depth, on_path)
    found = [(a, b, "scatter") for a, b in _scatter_spans(depth, on_path, bottom, running)]
    found += [(a, b, "scatter") for a, b in _bridged_spans(depth, on_path, bottom)]
    if step is not None:
        found += [(a, b, "steep") for a, b in _steep_spans(depth, on_path, step, running)]
    spans: list[list] = []
    for a, b, why in sorted(found):
        if spans and a <= spans[-1][1] + RESUME:
            spans[-1][1] = max(spans[-1][1], b)
            if why not in spans[-1][2]:
                spans[-1][2] += "+" + why
        else:
            spans.append([a, b, why])
    return [
        LostStretch(a, b, float(trel[a]), float(trel[b]), float(np.mean(bottom[a : b + 1])), why)
        for a, b, why in spans
        if b - a + 1 >= MIN_SOUNDINGS
    ]


def lost_mask(n: int, stretches: list[LostStretch]) -> np.ndarray:
    """True for the readings inside the stretches."""
    mask = np.zeros(n, bool)
    for s in stretches:
        mask[s.i0 : s.i1 + 1] = True
    return mask


def runs_of(lost: np.ndarray, trel: np.ndarray) -> list[LostStretch]:
    """The runs of readings marked lost, as stretches (whose share on a seabed is not known: NaN)."""
    edges = np.flatnonzero(np.diff(np.r_[0, lost.astype(int), 0]))
    return [
        LostStretch(int(a), int(b), float(trel[a]), float(trel[b]), float("nan"))
        for a, b in zip(edges[::2], edges[1::2] - 1, strict=True)
    ]


def running(values: np.ndarray, window: int, fn) -> np.ndarray:
    """`fn` (nan-aware) over a centred window of `window` rows, the window shrunk at the ends."""
    half = window // 2
    padded = np.concatenate([np.full(half, np.nan), values, np.full(half, np.nan)])
    view = np.lib.stride_tricks.sliding_window_view(padded, window)
    if fn is np.nanmedian:
        return _nanmedian_rows(view)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN window gives NaN, as it should
        return fn(view, axis=1)


def _nanmedian_rows(view: np.ndarray, rows: int = 65_536) -> np.ndarray:
    """np.nanmedian of every row, equal to it to the bit (the middle of the sorted finite values, the
    mean of the two middle ones for an even count, NaN for none), a block of rows at a time: numpy's own
    goes through masked arrays for short rows, 14 s for a million 61-wide windows."""
    out = np.empty(len(view))
    for a in range(0, len(view), rows):
        s = np.sort(view[a : a + rows], axis=1)  # NaN last
        k = np.count_nonzero(~np.isnan(s), axis=1)
        idx = np.arange(len(s))
        lo, hi = s[idx, np.maximum(k - 1, 0) // 2], s[idx, k // 2 - (k == 0)]
        out[a : a + rows] = np.where(k > 0, np.where(k % 2 == 1, lo, (lo + hi) / 2), np.nan)
    return out


def readings_of(parts: list[np.ndarray]) -> np.ndarray:
    """Each row's reading: rows that repeat the row before (a table sampled faster than the sensor
    holds its last reading) are one reading, so that a window counts readings, not rows (at 4 rows
    a sounding, a run of two false echoes filled 8 of 9 rows and beat the median)."""
    same = np.ones(len(parts[0]) - 1, bool) if len(parts[0]) else np.zeros(0, bool)
    for p in parts:
        same &= (p[1:] == p[:-1]) | (np.isnan(p[1:]) & np.isnan(p[:-1]))
    if not len(same) or same.mean() < HELD_SHARE:
        # a coarse column repeats too (PacCupStart's DBT: 57 % of rows), but not as a rule: counted
        # by readings, its window spanned a minute of a steep channel and flagged 71 real soundings
        return np.arange(len(parts[0]))
    return np.concatenate([[0], np.cumsum(~same)])


def path_tolerance(depth: np.ndarray | float) -> np.ndarray:
    """How far a step of the seabed's path may go before it costs a jump (the spike floor)."""
    return PATH_FLOOR_M + PATH_FLOOR_SHARE * np.abs(depth)


@dataclass
class DepthLost:
    """The test on one column of soundings: per reading and per row."""

    group: np.ndarray  # each row's reading
    first: np.ndarray  # each reading's first row
    on_path: np.ndarray  # per reading: on the seabed's continuous path
    stretches: list[LostStretch]  # by reading
    lost: np.ndarray  # per reading: inside a stretch

    @property
    def rows(self) -> np.ndarray:
        """Per row: inside a stretch."""
        return self.lost[self.group]

    def row_span(self, s: LostStretch) -> tuple[int, int]:
        """The first and last row of a stretch."""
        last = np.flatnonzero(self.group == s.i1)
        return int(self.first[s.i0]), int(last[-1])


def depth_lost(depth: np.ndarray, trel: np.ndarray, xy: np.ndarray | None = None) -> DepthLost:
    """The bottom lost in a column of soundings (one per row, NaN where none; ``trel``: each row's
    time in seconds; ``xy``: its position in metres, for the steepness test): readings grouped, the
    seabed's path, the stretches."""
    group = readings_of([depth])
    first = np.flatnonzero(np.diff(group, prepend=-1))
    d = depth[first]
    on_path = seabed_path(d, path_tolerance(d))
    step = None
    if xy is not None:
        pos = xy[first]
        step = np.r_[0.0, np.hypot(*np.diff(pos, axis=0).T)]
    stretches = lost_stretches(d, on_path, trel[first], running, step)
    return DepthLost(group, first, on_path, stretches, lost_mask(len(d), stretches))
