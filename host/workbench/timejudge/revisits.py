"""Where the boat comes back: pairs of samples close in space and apart in time, and the stretches of track
that are their paired unit.

A static map cannot explain why two passes over one place differ; a change in time can (a tide, a seiche, a
water level, a drift). Hydrographers judge it the same way at crosslines (CARIS HIPS, QPS Qimera): the
differences where passes meet, against the time between them.

Two samples are a revisit pair when they lie within `radius` of each other and in different stretches of
the survey's time. A stretch is as long as the residuals stay correlated along the track (twice their
integral time scale, at least two minutes): samples in different stretches carry nearly independent errors,
so whole stretches can be exchanged in a permutation test (host/workbench/timejudge/judge.py). The
radius is half the map's length scale: within it a Matern 3/2 field keeps 78 % of its correlation, and
what the field does between the two samples the map's prediction removes (the pairs are differences of
residuals), its gradient across the pair too (time_forms.Projector). A smaller radius (a fifth: 95 %)
left the injected seiche of tests/real_cases.py 31 crossings and p 0.048; half gives it 85 and p 0.001,
while the simulator's surveys without a change in time stay null (p 0.11-0.67).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# the errors' memory is measured on the residuals less their running mean over this long (s): the shortest
# period the revisits judge (host/workbench/timejudge/judge.py MIN_PERIOD_S)
HIGHPASS_S = 600.0
# two passes over one place are judged at least this far apart in time (s)
MIN_STRETCH_S = 120.0
# a stretch is this many integral time scales of the residuals long
STRETCH_SCALES = 2.0
# the radius of a revisit, as a share of the map's length scale, and its bounds (m)
RADIUS_SHARE = 0.5
MIN_RADIUS_M, MAX_RADIUS_M = 3.0, 250.0
# pairs are formed on at most this many rows, evenly spread in time (a pass is sampled far finer than its
# errors decorrelate)
MAX_PAIR_ROWS = 4000
# and at most this many pairs are kept (a random sample, fixed seed)
MAX_PAIRS = 6000


def correlation_time(t: np.ndarray, r: np.ndarray, highpass_s: float = HIGHPASS_S) -> float:
    """The integral time scale (s) of the errors in `r` along the track: the autocorrelation of `r` on a
    1-s grid, less its running mean over `highpass_s`, summed up to its first zero crossing. The running
    mean takes out what changes slowly (a change in time, the map's misfit along a leg), which is what the
    revisits judge, not the errors' memory."""
    order = np.argsort(t, kind="stable")
    t, r = t[order], r[order]
    if len(t) < 3 or np.ptp(t) < 2.0:
        return 0.0
    grid = np.arange(t[0], t[-1], 1.0)
    x = np.interp(grid, t, r)
    w = int(min(highpass_s, len(x)))
    if w > 1:
        c = np.cumsum(np.r_[0.0, x])
        lo = np.clip(np.arange(len(x)) - w // 2, 0, len(x))
        hi = np.clip(np.arange(len(x)) + w // 2 + 1, 0, len(x))
        x = x - (c[hi] - c[lo]) / (hi - lo)
    x = x - x.mean()
    if not np.any(x):
        return 0.0
    f = np.fft.rfft(x, 2 * len(x))
    ac = np.fft.irfft(f * np.conj(f))[: len(x)]
    ac = ac / ac[0]
    cut = int(np.argmax(ac < 0)) if (ac < 0).any() else len(ac)
    return float(ac[:cut].sum())


def stretch_length(t: np.ndarray, r: np.ndarray) -> float:
    """How long a stretch of track must be for its errors to be nearly independent of the next one's."""
    return max(MIN_STRETCH_S, STRETCH_SCALES * correlation_time(t, r))


def map_lengthscale(sm) -> float:
    """A fitted survey model's spatial length scale (m), or the survey's extent when it has none."""
    ell = sm.primary.position_lengthscale_
    return ell if ell is not None else float(np.ptp(sm.survey.xy, axis=0).max())


def target_radius(sm) -> float:
    """The revisit radius for a fitted survey model: REVISIT_RADIUS_M under depth (a bed has detail at
    every scale, and soundings a few metres apart already differ), half the map's length scale for a
    smooth field (a current, the wind, a temperature)."""
    from forcemap.host.workbench.depth.water_level import REVISIT_RADIUS_M
    from forcemap.host.workbench.survey.table import family

    if family(sm.target) == "depth":
        return REVISIT_RADIUS_M
    return revisit_radius(map_lengthscale(sm))


def revisit_radius(lengthscale_m: float) -> float:
    """The radius (m) within which two samples count as the same place, from the map's length scale."""
    return float(np.clip(RADIUS_SHARE * lengthscale_m, MIN_RADIUS_M, MAX_RADIUS_M))


@dataclass
class RevisitPairs:
    """Revisit pairs (row indices, the earlier first), each row's stretch, and how they were formed."""

    pairs: np.ndarray  # (p, 2)
    stretch: np.ndarray  # (n,) each row's stretch index
    n_stretches: int
    stretch_s: float
    radius_m: float
    t: np.ndarray  # (n,) s since the first row's time
    start_s: float = 0.0  # the first row's time in the times given (s since the survey's start)

    @property
    def crossings(self) -> int:
        """How many distinct pairs of stretches meet: the number of times a pass came back."""
        return int(self.crossing_index().max(initial=-1)) + 1

    def crossing_index(self) -> np.ndarray:
        """Each pair's crossing (the pair of stretches it joins), numbered 0 .. crossings - 1."""
        key = crossing_keys(self.pairs, self.stretch, self.n_stretches)
        return np.unique(key, return_inverse=True)[1].ravel()

    @property
    def rows(self) -> np.ndarray:
        return np.unique(self.pairs)

    def times(self, order: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The pairs' times; with `order` (a permutation of the stretches), each stretch moved to the time of
        the stretch `order` gives it, its samples keeping their place within it."""
        ta, tb = self.t[self.pairs[:, 0]], self.t[self.pairs[:, 1]]
        if order is None:
            return ta, tb
        shift = self.shifts(order)
        return ta + shift[self.stretch[self.pairs[:, 0]]], tb + shift[self.stretch[self.pairs[:, 1]]]

    def shifts(self, order: np.ndarray) -> np.ndarray:
        """How far (s) `order` moves each stretch: to the start of the stretch it gives it (any leading axes of
        `order`, one permutation per row, are kept)."""
        starts = self.stretch_s * np.arange(self.n_stretches)
        return starts[order] - starts


def revisit_pairs(
    xy: np.ndarray, t: np.ndarray, radius_m: float, stretch_s: float, seed: int = 0
) -> RevisitPairs:
    """Every pair of (thinned) rows within `radius_m` of each other and in different stretches of
    `stretch_s`, at least `stretch_s` apart in time; at most MAX_PAIRS of them."""
    from scipy.spatial import cKDTree

    start = float(np.min(t))
    t = np.asarray(t, float) - start
    n_st = max(2, int(np.ceil(np.ptp(t) / stretch_s)))
    stretch = np.minimum((t / stretch_s).astype(int), n_st - 1)
    rows = np.arange(0, len(t), max(1, int(np.ceil(len(t) / MAX_PAIR_ROWS))))
    p = rows[cKDTree(xy[rows]).query_pairs(radius_m, output_type="ndarray")]
    p = p[(np.abs(t[p[:, 0]] - t[p[:, 1]]) >= stretch_s) & (stretch[p[:, 0]] != stretch[p[:, 1]])]
    later = t[p[:, 0]] > t[p[:, 1]]
    p[later] = p[later][:, ::-1]
    p = balanced(p, stretch, n_st, seed)
    return RevisitPairs(p.reshape(-1, 2), stretch, n_st, float(stretch_s), float(radius_m), t, start)


def crossing_keys(pairs: np.ndarray, stretch: np.ndarray, n_stretches: int) -> np.ndarray:
    """Each pair's crossing as one number: the pair of stretches it joins."""
    return stretch[pairs[:, 0]] * n_stretches + stretch[pairs[:, 1]]


def balanced(p: np.ndarray, stretch: np.ndarray, n_st: int, seed: int) -> np.ndarray:
    """At most MAX_PAIRS pairs, as evenly as possible over the crossings (pairs of stretches): a boat that
    circles at a mark for minutes makes thousands of pairs of one crossing, and a uniform sample of the
    pairs would judge time almost only there."""
    if len(p) <= MAX_PAIRS:
        return p
    key = crossing_keys(p, stretch, n_st)
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(p))
    key = key[order]
    # each pair's rank within its crossing, in the random order; keep the lowest ranks up to MAX_PAIRS
    first = np.argsort(key, kind="stable")
    rank = np.empty(len(p), int)
    sk = key[first]
    starts = np.flatnonzero(np.r_[True, sk[1:] != sk[:-1]])
    rank[first] = np.arange(len(p)) - np.repeat(starts, np.diff(np.r_[starts, len(p)]))
    keep = order[np.argsort(rank, kind="stable")[:MAX_PAIRS]]
    return p[np.sort(keep)]
