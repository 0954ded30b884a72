"""The soundings judged at import and by the workbench: which the sounder held, the stretches where it
lost the bottom, and why every other sounding is rejected (issue 37, issue 61).

A stretch is judged on whether its readings agree with a smooth bed, not on whether each reading looks
wild (forcemap.host.fuse.smooth_bed: the layers the readings form, the scale from their own robust
scatter; forcemap.host.fuse.sounding_reasons: which layer is the bottom, and each reading's reason).
The bottom is lost where most readings of a window lie on no bed, or no layer there can be the bottom;
the stretch runs over those windows, and the runs of readings inside it that continue the bed around
them are held. Every other reading is rejected with its reason: the bottom lost, a spike, a false
bottom, a second echo. Rows are never dropped.

One home for the import (forcemap.host.convert.depth_findings: a ``qa.depth.bottom_lost`` finding and
each row's reason in ``bottom_lost``) and the workbench (forcemap.host.workbench.spikes: the rows left
out of the depth map): ``depth_lost`` runs the whole judgement on a column of soundings.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.fuse.sounding_reasons import HELD, LOST, judge, runs

# rows are grouped into readings when at least this share repeats the row before (the simulator's
# 4 rows per 1-Hz sounding: 75 %)
HELD_SHARE = 0.7
# the spike floor of a sounding (0.5 m + 5 % of the depth): what a step of the seabed may do
PATH_FLOOR_M = 0.5
PATH_FLOOR_SHARE = 0.05
NO_SOUNDING = -1


@dataclass
class LostStretch:
    """One stretch where the bottom was lost: readings ``i0`` to ``i1`` (inclusive)."""

    i0: int
    i1: int
    t0: float  # seconds since the survey's start
    t1: float
    share: float  # the share of its soundings held (on the bed)
    why: str = "scatter"

    @property
    def n(self) -> int:
        return self.i1 - self.i0 + 1

    def text(self) -> str:
        held = "" if not np.isfinite(self.share) else f", {self.share:.0%} on a smooth bed"
        return f"{self.t0 / 60:.1f}-{self.t1 / 60:.1f} min ({self.n} soundings{held})"


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
    """How far a seabed may step between two soundings beyond its slope (the spike floor)."""
    return PATH_FLOOR_M + PATH_FLOOR_SHARE * np.abs(depth)


@dataclass
class DepthLost:
    """The judgement of one column of soundings: per reading and per row."""

    group: np.ndarray  # each row's reading
    first: np.ndarray  # each reading's first row
    on_path: np.ndarray  # per reading: held, on the bed (the soundings maps are made from)
    stretches: list[LostStretch]  # by reading
    lost: np.ndarray  # per reading: rejected as the bottom lost
    reason: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # per reading; -1: none
    bed: np.ndarray = field(default_factory=lambda: np.zeros(0))  # the bed's depth at each reading
    sd: np.ndarray = field(default_factory=lambda: np.zeros(0))  # its noise there (1 sd, m)

    @property
    def rows(self) -> np.ndarray:
        """Per row: rejected as the bottom lost."""
        return self.lost[self.group]

    @property
    def rejected(self) -> np.ndarray:
        """Per reading: rejected, for any reason."""
        return self.reason > HELD

    @property
    def row_reasons(self) -> np.ndarray:
        """Per row: its reading's reason (sounding_reasons' codes; -1 where there is no sounding)."""
        return self.reason[self.group]

    def row_span(self, s: LostStretch) -> tuple[int, int]:
        """The first and last row of a stretch."""
        last = np.flatnonzero(self.group == s.i1)
        return int(self.first[s.i0]), int(last[-1])


def _along(trel: np.ndarray, xy: np.ndarray | None) -> tuple[np.ndarray, bool]:
    """Where each reading lies along the track: metres travelled where most have a position, else
    seconds."""
    if xy is None or np.isfinite(xy).all(axis=1).mean() < 0.5:
        return np.asarray(trel, float), False
    pos = np.asarray(xy, float)
    step = np.hypot(*np.diff(pos, axis=0).T)
    return np.r_[0.0, np.cumsum(np.nan_to_num(step))], True


def depth_lost(depth: np.ndarray, trel: np.ndarray, xy: np.ndarray | None = None) -> DepthLost:
    """The soundings of a column judged (one per row, NaN where none; ``trel``: each row's time in
    seconds; ``xy``: its position in metres, for the distance travelled): readings grouped, each
    one's reason, the lost stretches."""
    group = readings_of([depth])
    first = np.flatnonzero(np.diff(group, prepend=-1))
    d = depth[first]
    reason = np.where(np.isfinite(d), HELD, NO_SOUNDING)
    bed, sd, region = np.full(len(d), np.nan), np.full(len(d), np.nan), np.zeros(len(d), bool)
    idx = np.flatnonzero(np.isfinite(d))
    x, along = _along(trel[first], None if xy is None else xy[first])
    if len(idx) > 2:
        j = judge(d[idx], x[idx], along)
        reason[idx], bed[idx], sd[idx], region[idx] = j.reason, j.bed, j.layers.sd, j.lost_region
    t = trel[first]
    stretches = [
        LostStretch(int(idx[a]), int(idx[b]), float(t[idx[a]]), float(t[idx[b]]),
                    float(np.mean(reason[idx[a] : idx[b] + 1] == HELD)))
        for a, b in runs(region[idx])
    ]  # fmt: skip
    return DepthLost(group, first, reason == HELD, stretches, reason == LOST, reason, bed, sd)
