"""The smooth beds the soundings form: through each reading, the bed its neighbours support, and how surely.

A sounder that holds the bottom gives readings on one smooth bed along the track, its own noise about
it; one that has lost the bottom gives readings that agree with no smooth bed (scatter), or with a bed
of their own that is not the bottom (a false bottom above it, a second echo at twice its depth). So
each reading asks its neighbours (HALF readings either side, the window): is there a smooth bed through
me that more of you lie on than chance would put there?

- **The bed through a reading** starts as the line along the track through it that the most readings
  of its window lie within K sd of (``x`` the distance travelled where the positions are known, its
  slope at most MAX_SLOPE, a seabed's: a damped sounder gliding from 2 to 108 m within 40 m of travel
  is no bed; else the time, any slope): each neighbour allows an interval of slopes, and a sweep over
  their ends finds the one most allow. The layer then grows along the least-squares parabola through
  its readings (a curved bed is followed past where the line leaves it), from the readings on both
  sides of the reading or on one side only, whichever stands out more (a channel's floor bends
  sharply: smooth on each side).
- **Chance**: the readings beside the layer (out to FLANK times its band) are the scatter's own
  density there, wherever in the water column it gathers; were the band and its flanks filled
  evenly, the layer's support beyond the two readings that make any line is a binomial tail, times
  the lines tried (one per neighbour). Below ALPHA, the reading lies on a layer.
- **The scale** is the data's, never a picked one: for each reading, the robust sd (1.4826 MAD) of
  its window about the parabola through it, at the smallest of SCALES (a factor SCALE_STEP apart,
  from the readings' resolution) at which most of the window lies within K sd and gathers about the
  curve as noise does (68 % within 1 sd: ``peaked``); a cloud of scatter fills a band evenly, and is
  measured nowhere. Nor is a bed's noise ever more than the spike floor (``floor_of``). The bed's sd
  at a reading is the running median over the windows where most readings were measured (a
  sounder's noise changes slowly; a stretch of scatter takes the scale of the beds on either side).

K = 3 keeps 99.7 % of a held sounder's Gaussian noise; ALPHA = 1e-3 lets about one reading in a
thousand of pure scatter pass for a layer (measured: 0 to 7.5e-4 on uniform scatter at every scale).
forcemap.host.fuse.sounding_reasons decides which layer is the bottom and why each other reading is
rejected.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.special import betainc

HALF = 15  # readings either side of a reading: its window
SCALE_HALF = HALF  # ... where its noise is measured
K = 3.0  # a reading agrees with a bed within K sd
ALPHA = 1e-3  # a layer: support beyond what scatter gives with this probability
MAX_SLOPE = 1.0  # the steepest seabed a layer follows, m per m travelled (45 deg)
SCALE_STEP = 2.0**0.5
MAD_TO_SD = 1.4826
BLOCK = 2048  # readings whose windows are formed at once
NO_SLOPE_LIMIT = 1e6  # against time: any slope
FLANK = 10.0  # the scatter's density beside a layer: out to this many half-bands from it
FLOOR_M, FLOOR_SHARE = 0.5, 0.05  # the spike floor (floor_of)
GROW = 3  # rounds a layer's readings are grown along the parabola through them


@dataclass
class Layers:
    """Per reading: the layer through it (its support, the chance of that, its level and slope at the
    reading) and the bed's noise there (1 sd, m)."""

    x: np.ndarray  # along the track: m travelled, or s
    sd: np.ndarray
    support: np.ndarray  # readings of the window on the layer, the reading included
    logp: np.ndarray  # natural log of the chance of that support in scatter
    level: np.ndarray  # the layer's depth at the reading (the parabola through its readings)
    slope: np.ndarray  # per unit of x
    curve: np.ndarray  # the parabola's second-order term, per unit of x squared
    reach: np.ndarray  # (n, 2): how far before and after the reading its readings go, in x
    max_slope: float = MAX_SLOPE  # the steepest bed (per unit of x; 0: none known, against time)

    @property
    def on(self) -> np.ndarray:
        """The readings that lie on a layer (one that chance does not explain)."""
        return self.logp < np.log(ALPHA)

    def at(self, j: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The depth of reading ``j``'s layer at ``x``: its parabola where its readings are, straight
        on beyond them (a parabola runs away outside its data)."""
        dx = x - self.x[j]
        dc = np.clip(dx, self.reach[j, 0], self.reach[j, 1])
        c = self.curve[j]
        return self.level[j] + self.slope[j] * dx + c * dc * dc + 2.0 * c * dc * (dx - dc)


def windows(n: int, rows: np.ndarray, half: int = HALF) -> tuple[np.ndarray, np.ndarray]:
    """The window of each of ``rows``: its neighbours' indices (clipped) and which are real."""
    j = rows[:, None] + np.arange(-half, half + 1)[None, :]
    return np.clip(j, 0, max(n - 1, 0)), (j >= 0) & (j < n)


def _slope_intervals(
    r: np.ndarray, tau: np.ndarray, w: np.ndarray, valid: np.ndarray, bmax: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each neighbour's interval of slopes whose line through the reading passes within ``w`` of it."""
    with np.errstate(divide="ignore", invalid="ignore"):
        lo, hi = (r - w) / tau, (r + w) / tau
    lo, hi = np.where(tau < 0, hi, lo), np.where(tau < 0, lo, hi)
    zero = tau == 0
    near = np.abs(r) <= w
    lo = np.where(zero, np.where(near, -bmax, np.inf), lo)
    hi = np.where(zero, np.where(near, bmax, -np.inf), hi)
    lo, hi = np.maximum(lo, -bmax), np.minimum(hi, bmax)
    ok = valid & (lo <= hi)
    return np.where(ok, lo, 0.0), np.where(ok, hi, 0.0), ok


def best_line(
    d: np.ndarray, x: np.ndarray, w: np.ndarray, bmax: float, rows: np.ndarray, half: int = HALF,
    side: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each of ``rows``, the line through it that the most readings of its window lie within ``w``
    of (``side`` -1: of the readings before it only, 1: after it, 0: both): every window reading's
    distance from it (inf where none), which lie within ``w`` (a mask over the window), and the
    window's readings it looked at."""
    j, valid = windows(len(d), rows, half)
    valid &= np.isfinite(d[j]) & (side * np.arange(-half, half + 1)[None, :] >= 0)
    r, tau = d[j] - d[rows][:, None], x[j] - x[rows][:, None]
    lo, hi, ok = _slope_intervals(r, tau, w[rows][:, None], valid, bmax)
    # the sweep: a start (+1) before an end (-1) at the same slope, the empty ones counting nothing
    value = np.concatenate([lo, hi], axis=1)
    kind = np.concatenate([np.where(ok, 0, 2), np.where(ok, 1, 2)], axis=1)
    order = np.lexsort((kind, value), axis=-1)
    v = np.take_along_axis(value, order, axis=1)
    step = np.take_along_axis(np.where(kind == 0, 1, np.where(kind == 1, -1, 0)), order, axis=1)
    count = np.cumsum(step, axis=1)
    k = np.argmax(count, axis=1)
    nxt = np.minimum(k + 1, v.shape[1] - 1)
    rr = np.arange(len(rows))
    b = 0.5 * (v[rr, k] + v[rr, nxt])
    dev = np.where(valid, np.abs(r - b[:, None] * tau), np.inf)
    return dev, dev <= w[rows][:, None] * (1 + 1e-9), valid


def tail(k: np.ndarray, n: np.ndarray, p: np.ndarray | float) -> np.ndarray:
    """log P(X >= k), X binomial with n trials of probability p; k and n need not be whole (counts of
    readings scaled to independent ones)."""
    k, n = np.asarray(k, float), np.asarray(n, float)
    with np.errstate(all="ignore"):
        out = np.log(np.maximum(betainc(np.maximum(k, 1e-9), np.maximum(n - k + 1, 1e-9), p), 1e-300))
    return np.where(k <= 0, 0.0, np.where(k > n, np.log(1e-300), out))


def chance(
    support: np.ndarray, flank: np.ndarray, n: np.ndarray, level: np.ndarray, w: np.ndarray,
    top: float, eff: float,
) -> np.ndarray:
    """log P(``support`` or more of the readings within FLANK w of a line at ``level`` lie within w of
    it, were they scattered evenly over the band and its flanks), times the n - 1 lines through the
    reading and another: the flanks are the scatter's own density beside the layer, wherever in the
    sounder's range it gathers (less what lies above the surface or below the deepest reading). The
    counts are of independent readings: ``eff`` of a row each (``independence``)."""
    lower = np.maximum(0.0, (level - w) - np.maximum(level - FLANK * w, 0.0))
    upper = np.maximum(0.0, np.minimum(level + FLANK * w, top) - (level + w))
    p_in = 2 * w / (2 * w + lower + upper)
    extra = (support - 2) * eff  # beyond the reading and the one that made the line
    logp = tail(extra, extra + flank * eff, p_in) + np.log(np.maximum((n - 1) * eff, 1.0))
    return np.where(support > 2, np.minimum(logp, 0.0), 0.0)


def independence(d: np.ndarray) -> float:
    """The share of a row that is an independent reading: 1 over the median length of the runs of
    equal readings (a table that repeats the sounder's last reading until the next, 57 % of
    PacCupStart's rows, counts each of its readings once, not once a row)."""
    if len(d) < 2:
        return 1.0
    edges = np.flatnonzero(np.r_[True, d[1:] != d[:-1], True])
    return 1.0 / max(float(np.median(np.diff(edges))), 1.0)


def _curve_fit(
    d: np.ndarray, x: np.ndarray, rows: np.ndarray, inside: np.ndarray, half: int, bmax: float
) -> tuple[np.ndarray, ...]:
    """The least-squares parabola through each row's readings on its layer (a line where they are
    fewer than four, or where the parabola would be steeper than ``bmax`` among them): its level,
    slope and second-order term at the row, how far before and after the row they go, and every
    window reading's residual."""
    j, _ = windows(len(d), rows, half)
    r, tau = d[j] - d[rows][:, None], x[j] - x[rows][:, None]
    lo = np.where(inside, tau, np.inf).min(axis=1)
    hi = np.where(inside, tau, -np.inf).max(axis=1)
    lo = np.minimum(np.where(np.isfinite(lo), lo, 0.0), 0.0)
    hi = np.maximum(np.where(np.isfinite(hi), hi, 0.0), 0.0)
    scale = np.maximum(np.maximum(-lo, hi), 1e-9)[:, None]
    u = tau / scale  # well conditioned
    basis = np.stack([np.ones_like(u), u, u * u], axis=2)
    w = inside.astype(float)[:, :, None]
    gram = np.einsum("rwi,rwj->rij", basis * w, basis) + 1e-9 * np.eye(3)
    rhs = np.einsum("rwi,rw->ri", basis * w, r)
    coef = np.linalg.solve(gram, rhs[:, :, None])[:, :, 0]
    steep = np.maximum(np.abs(coef[:, 1] + 2 * coef[:, 2] * lo / scale[:, 0]),
                       np.abs(coef[:, 1] + 2 * coef[:, 2] * hi / scale[:, 0])) > bmax * scale[:, 0]  # fmt: skip
    line = (inside.sum(axis=1) < 4) | steep
    gram[line, 2, 2] += 1e12  # no second-order term
    coef = np.linalg.solve(gram, rhs[:, :, None])[:, :, 0]
    res = r - np.einsum("rwi,ri->rw", basis, coef)
    s0 = scale[:, 0]
    return d[rows] + coef[:, 0], coef[:, 1] / s0, coef[:, 2] / s0**2, np.c_[lo, hi], res


def span_of(d: np.ndarray) -> float:
    """R: the span of depths the sounder reported."""
    f = d[np.isfinite(d)]
    return float(np.ptp(f)) if len(f) else 0.0


def resolution(d: np.ndarray) -> float:
    """The readings' step: the smallest change between successive ones that is not zero."""
    f = np.abs(np.diff(d[np.isfinite(d)]))
    f = f[f > 1e-9]
    return float(np.min(f)) if len(f) else 0.01


def peaked(core: np.ndarray, support: np.ndarray, n: np.ndarray, eff: float) -> np.ndarray:
    """log P(``core`` or more of the ``support`` readings within 3 s of a line lie within s of it, were
    they spread evenly over the band), times the n - 1 lines tried: small where they gather about the
    line as a sounder's noise does (68 % within 1 sd, 99.7 % within 3), not where a cloud of scatter
    fills the band. Counts of independent readings, ``eff`` a row."""
    logp = tail(core * eff, support * eff, 1.0 / K) + np.log(np.maximum((n - 1) * eff, 1.0))
    return np.minimum(logp, 0.0)


def floor_of(depth: np.ndarray) -> np.ndarray:
    """The most a held bottom's noise can be (1 sd): the spike floor, FLOOR_M + FLOOR_SHARE of the
    depth, what a seabed may step between two soundings (bottom_lost.path_tolerance). A cloud of
    returns spread over a fifth of the water column gathers about its middle as noise does, and is no
    bed: Lake Geneva's thermocline scatter, 30-75 m, would pass for one with an sd of 5 to 12 m."""
    return FLOOR_M + FLOOR_SHARE * np.abs(depth)


def _best_scale(d: np.ndarray, x: np.ndarray, bmax: float, big: float, eff: float) -> np.ndarray:
    """Per reading, the robust sd of its window about a line through it, at the smallest of SCALES at
    which most of the window lies within K of it and gathers about the line as noise does
    (``peaked``). NaN where none: the noise of a bed is measured where the sounder holds it, never in
    scatter, which fills a band evenly at any scale (a wide enough band always holds most of it)."""
    n = len(d)
    lo = max(resolution(d) / 2.0, 1e-3)
    hi = max(big / (2.0 * K), lo)
    scales = lo * SCALE_STEP ** np.arange(int(np.log(hi / lo) / np.log(SCALE_STEP)) + 1)
    best = np.full(n, np.nan)
    top = float(np.max(d))
    for s in scales:
        todo = np.flatnonzero(np.isnan(best))
        w = np.full(n, K * s)
        for a in range(0, len(todo), BLOCK):
            rows = todo[a : a + BLOCK]
            _, inside, valid = best_line(d, x, w, bmax, rows, SCALE_HALF)
            # about the least-squares parabola through them: the line through the reading carries
            # its own noise, off the middle of the band, and misses a curved bed's bend
            res = np.abs(_curve_fit(d, x, rows, inside, SCALE_HALF, bmax)[-1])
            res = np.where(valid, res, np.inf)
            support, m = (res <= K * s).sum(axis=1), valid.sum(axis=1)
            logp = peaked((res <= s).sum(axis=1), support, m, eff)
            # the robust sd of the readings in the band (at that scale, the band is 3 to 4 sd wide:
            # the MAD of what it holds is hardly truncated)
            sd = np.maximum(MAD_TO_SD * np.nanmedian(np.where(res <= K * s, res, np.nan), axis=1), lo)
            flank = (res <= FLANK * K * s).sum(axis=1) - support
            stands = chance(support, flank, m, d[rows], np.full(len(rows), K * s), top, eff)
            found = (logp < np.log(ALPHA)) & (stands < np.log(ALPHA)) & (sd <= floor_of(d[rows]))
            best[rows[found]] = sd[found]
    return best


def running_median(values: np.ndarray, half: int = HALF) -> np.ndarray:
    """The median of the finite values over each centred window of 2 half + 1 (NaN where none)."""
    padded = np.concatenate([np.full(half, np.nan), values, np.full(half, np.nan)])
    view = np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1)
    s = np.sort(view, axis=1)  # NaN last
    k = np.count_nonzero(~np.isnan(s), axis=1)
    idx = np.arange(len(s))
    lo, hi = s[idx, np.maximum(k - 1, 0) // 2], s[idx, np.maximum(k, 1) // 2 - (k == 0)]
    return np.where(k > 0, np.where(k % 2 == 1, lo, (lo + hi) / 2), np.nan)


def _filled(values: np.ndarray, default: float) -> np.ndarray:
    """NaN entries interpolated from the finite ones on either side (a stretch of scatter takes the
    scale of the beds around it); ``default`` where none is."""
    ok = np.flatnonzero(np.isfinite(values))
    if not len(ok):
        return np.full(len(values), default)
    return np.interp(np.arange(len(values)), ok, values[ok])


def held_median(values: np.ndarray, held: np.ndarray, default: float) -> np.ndarray:
    """The running median of ``values`` of the ``held`` readings over the windows where most readings
    are held (a few layers found by chance in scatter do not set the scale), and, where they are not,
    interpolated from either side (``_filled``)."""
    med = running_median(np.where(held, values, np.nan))
    share = np.convolve(held.astype(float), np.ones(2 * HALF + 1), "same")
    have = np.convolve(np.ones(len(held)), np.ones(2 * HALF + 1), "same")
    return _filled(np.where(2 * share >= have, med, np.nan), default)


def layers(d: np.ndarray, x: np.ndarray, along_track: bool) -> Layers:
    """The layer through every reading (``d`` finite, in time order; ``x`` metres travelled when
    ``along_track``, else seconds)."""
    n = len(d)
    big = max(span_of(d), 10.0 * resolution(d))
    bmax = MAX_SLOPE if along_track else NO_SLOPE_LIMIT
    floor = resolution(d) / np.sqrt(12.0)
    top = float(np.max(d)) if n else 0.0
    eff = independence(d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        first = _best_scale(d, x, bmax, big, eff)
        held = np.isfinite(first)
        sd = np.fmax(held_median(first, held, resolution(d)), floor)
    best = None
    for side in (0, -1, 1):  # a bed that bends sharply (a channel's floor) is smooth on each side
        fits = [_layer_block(d, x, sd, bmax, np.arange(a, min(n, a + BLOCK)), top, eff, side)
                for a in range(0, n, BLOCK)]  # fmt: skip
        one = [np.concatenate(f) for f in zip(*fits, strict=True)]
        if best is None:
            best = one
        else:
            better = one[-1] < best[-1]
            best = [np.where(better if b.ndim == 1 else better[:, None], o, b)
                    for o, b in zip(one, best, strict=True)]  # fmt: skip
    level, slope, curve, reach, support, logp = best
    return Layers(np.asarray(x, float), sd, support, logp, level, slope, curve, reach,
                  MAX_SLOPE if along_track else 0.0)  # fmt: skip


def _layer_block(
    d: np.ndarray, x: np.ndarray, sd: np.ndarray, bmax: float, rows: np.ndarray, top: float,
    eff: float, side: int,
) -> tuple[np.ndarray, ...]:
    """The layers through ``rows`` (from the readings on ``side`` of each, best_line's): the best
    line's readings within K sd, grown along the parabola through them (a curved bed is followed past
    where the line leaves it), and how surely."""
    w = K * sd[rows]
    _, inside, valid = best_line(d, x, K * sd, bmax, rows, HALF, side)
    for _ in range(GROW):
        res = _curve_fit(d, x, rows, inside, HALF, bmax)[-1]
        inside = valid & (np.abs(res) <= w[:, None])
    level, slope, curve, reach, res = _curve_fit(d, x, rows, inside, HALF, bmax)
    support = inside.sum(axis=1)
    flank = (valid & (np.abs(res) <= FLANK * w[:, None])).sum(axis=1) - support
    logp = chance(support, flank, valid.sum(axis=1), d[rows], w, top, eff)
    # the layer is the reading's only where the reading lies on it still: a line steep enough to
    # reach a bed nearby from a reading of scatter grows along the bed, and leaves the reading off it
    return level, slope, curve, reach, support, np.where(inside[:, HALF], logp, 0.0)
