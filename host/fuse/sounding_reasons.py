"""Which layer is the bottom, and why every other sounding is rejected: held, the bottom lost, a spike, a
false bottom, a second echo.

The layers come from forcemap.host.fuse.smooth_bed (through each reading, the bed its neighbours
support, and how surely). At each reading the bed is chosen among the layers of its window by physics:

- a second echo (the pulse back from the bottom, the surface and the bottom again) lies at twice
  another layer's depth, at the reading and at both ends of its own readings: never the bed;
- nothing echoes from below the bottom: a layer with another layer deeper than it, or more readings
  deeper than it than on it (over a wider window, DEEPER_HALF; deeper beyond its band and beyond what
  a bed can climb from its nearest reading, smooth_bed.MAX_SLOPE over the distance, not at twice its
  depth), is no bottom (a thermocline, a school of fish, a sounder's ringing);
- of the layers left, the reading's own where it is no shallower than the one most readings lie on
  (a bed bends: at a valley's side the floor is the best supported, and lower), else that one.

A reading within K sd of the bed is held, and its second echo seen. The sounder has lost the bottom
where no layer can be the bed, or where under half of a window's readings are held or seen and they
come in runs (the Wald-Wolfowitz test: a sounder locks and unlocks; false echoes over a bottom it
holds strike ping by ping, however many); stretches less than a window apart are one. Inside a
stretch a reading is held only on its own layer and where other runs of its window hold the same bed
(it continues the bed seen before or after it). Outside, a short steep run between two levels that a
seabed joins is held too (a channel's wall crossed in a few pings). Last, a run of held readings that
no seabed joins to the deeper runs beside it, and that lies above both, is cut off: a plateau between
a damped sounder's glides to the depth. Every other reading is rejected, for one reason:

| code | reason | the reading |
|---:|---|---|
| 0 | held | on the bed |
| 1 | lost_bottom | in a lost stretch, on no layer (or on one where no layer can be the bed) |
| 2 | spike | where the bottom is held, off it and on no layer of its own |
| 3 | false_bottom | on a layer of its own above the bed |
| 4 | second_echo | at twice the bed's depth |

Rows are never dropped: the import marks them (the samples' ``bottom_lost`` column carries the code),
and depth maps leave out every row whose code is not 0. ``judge_column`` runs it all on a table's
column (forcemap.host.convert.depth_findings at import and at `check`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from forcemap.host.fuse.bottom_lost import readings_of
from forcemap.host.fuse.smooth_bed import ALPHA, BLOCK, HALF, K, Layers, layers, windows
from scipy.stats import norm

HELD, LOST, SPIKE, FALSE_BOTTOM, SECOND_ECHO = 0, 1, 2, 3, 4
REASONS = {
    LOST: "the bottom lost",
    SPIKE: "spike",
    FALSE_BOTTOM: "false bottom",
    SECOND_ECHO: "second echo",
}
NAMES = {HELD: "held", LOST: "lost_bottom", SPIKE: "spike", FALSE_BOTTOM: "false_bottom",
         SECOND_ECHO: "second_echo"}  # fmt: skip
ECHO_SD = 8.0**0.5  # the sd of echo - 2 bed, the echo's own noise twice a sounding's
# readings either side over which a layer is no bottom where more lie deeper than on it: a sounder's
# ringing or a thermocline holds for tens of readings between its glides to the depth
DEEPER_HALF = 3 * HALF
LAYER = 3  # readings on a layer: the fewest that make one (two for a line, one that agrees)
# across the readings rejected between two runs held, the steepest seabed that joins them: 1 in 2
# (27 deg; bottom_lost.MAX_SLOPE); a wall seen reading by reading is followed to 1 in 1
CUT_SLOPE = 0.5
# every STRIDE-th reading of a window offers its layer as the bed (neighbours on one layer offer the
# same one; HALF is a multiple of it, so the row's own is among them)
STRIDE = 3


@dataclass
class Judged:
    """The soundings judged (per reading, in time order): the bed, its sd, each reading's reason, the
    lost stretches' readings and the share of each window's readings on the bed."""

    layers: Layers
    bed: np.ndarray  # the bottom's depth at each reading (NaN: none in its window)
    reason: np.ndarray  # int codes (module docstring)
    lost_region: np.ndarray  # bool: the sounder did not hold the bottom there
    held_share: np.ndarray

    @property
    def accepted(self) -> np.ndarray:
        return self.reason == HELD


def _echo_of(lay: Layers, j: np.ndarray, ok: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Which candidate layers of a row's window (axis 1) lie at twice another's depth (axis 2) at the
    row and at both ends of their own readings: a second echo follows the bed it doubles (a valley's
    side is at twice its floor at one point only)."""
    tol = (K * ECHO_SD * lay.sd[rows])[:, None, None]
    twice = np.ones(j.shape + (j.shape[1],), bool)
    x = lay.x
    for where in (x[rows][:, None], x[j] + lay.reach[j, 0], x[j] + lay.reach[j, 1]):
        here = np.broadcast_to(where, j.shape)[:, :, None]  # each echo candidate's point
        twice &= np.abs(lay.at(j[:, :, None], here) - 2.0 * lay.at(j[:, None, :], here)) <= tol
    return (twice & ok[:, None, :] & ok[:, :, None]).any(axis=2)


def _on_line(
    d: np.ndarray, lay: Layers, j: np.ndarray, k: np.ndarray, valid: np.ndarray
) -> np.ndarray:
    """Whether each reading ``k`` (axis 2) of a row's window lies on each candidate layer ``j``
    (axis 1)."""
    line = lay.at(j[:, :, None], lay.x[k][:, None, :])
    return valid[:, None, :] & (np.abs(d[k][:, None, :] - line) <= K * lay.sd[k][:, None, :])


def _no_deeper(d: np.ndarray, lay: Layers, j: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Whether each candidate layer ``j`` of a row has no more readings deeper than it than on it, and
    no layer of its own deeper than it (LAYER readings on one: the fewest that make one, two for a
    line and one that agrees), over the wider window (DEEPER_HALF): deeper beyond its band and beyond what a bed could descend
    (max_slope; against time, any: nothing counts) between its nearest reading and them, and not at
    twice its depth. A steep bed's far side is no evidence against it; a sounder's ringing between
    glides to the depth is."""
    wide, wvalid = windows(len(d), rows, DEEPER_HALF)
    won = _on_line(d, lay, j, wide, wvalid)
    x = lay.x
    xk = np.broadcast_to(x[wide][:, None, :], won.shape)
    prev = np.maximum.accumulate(np.where(won, xk, -np.inf), axis=2)
    nxt = np.minimum.accumulate(np.where(won, xk, np.inf)[:, :, ::-1], axis=2)[:, :, ::-1]
    gap = np.minimum(xk - prev, nxt - xk)
    line = lay.at(j[:, :, None], xk)
    dk, band = d[wide][:, None, :], K * lay.sd[wide][:, None, :]
    echo = np.abs(dk - 2.0 * line) <= band * ECHO_SD
    slope = lay.max_slope if lay.max_slope > 0 else np.inf  # against time, any bed is in reach
    with np.errstate(invalid="ignore"):
        deeper = wvalid[:, None, :] & (dk > line + band + slope * gap) & ~echo
    layered = (deeper & lay.on[wide][:, None, :]).sum(axis=2)  # deeper readings on a layer
    return (deeper.sum(axis=2) <= won.sum(axis=2)) & (layered < LAYER)


def _bed_block(d: np.ndarray, lay: Layers, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bed's depth at each of ``rows``. A layer of its window may be the bed where it is no second
    echo and no more readings lie deeper than it than on it; of those, the one most readings lie on,
    unless the row's own layer may and is no shallower than it (a curved bed is a line only near each
    reading: at a valley's side the valley floor is the best supported line, and shallower). NaN: none.
    And in how many runs the window's readings on that bed come."""
    j, valid = windows(len(d), rows)
    cand, me = j[:, ::STRIDE], HALF // STRIDE  # the candidates (the row's own layer among them)
    ok = valid[:, ::STRIDE] & lay.on[cand]
    c = lay.at(cand, lay.x[rows][:, None])  # each candidate layer at the row
    ok &= ~_echo_of(lay, cand, ok, rows)
    # each candidate (axis 1) at each reading of the window (axis 2)
    on = _on_line(d, lay, cand, j, valid)
    ok &= _no_deeper(d, lay, cand, rows)
    support = np.where(ok, on.sum(axis=2), -1)
    rr = np.arange(len(rows))
    best = np.argmax(support, axis=1)
    found = support[rr, best] > 0
    bed = np.where(found, c[rr, best], np.nan)
    own = ok[:, me] & (~found | (c[:, me] >= bed - K * lay.sd[rows]))
    pick = np.where(own, me, best)
    on_bed = on[rr, pick] & (own | found)[:, None]
    starts = (on_bed & ~np.c_[np.zeros(len(rows), bool), on_bed[:, :-1]]).sum(axis=1)
    return np.where(own, c[:, me], bed), starts


def _bridged(bed: np.ndarray, lay: Layers) -> np.ndarray:
    """The bed carried across a gap shorter than a window where no layer was found (a few pings of
    echoes in a row leave too few of the bottom to stand out): the straight line between the beds at
    its two ends, where a seabed can join them (their bands and max_slope over the distance)."""
    out = bed.copy()
    gone = ~np.isfinite(bed)
    edges = np.flatnonzero(np.diff(np.r_[0, gone.astype(int), 0]))
    x, sd = lay.x, lay.sd
    for a, b in zip(edges[::2], edges[1::2], strict=True):  # gone from a to b - 1
        if a == 0 or b == len(bed) or b - a > 2 * HALF + 1:
            continue
        reach = K * (sd[a - 1] + sd[b]) + (lay.max_slope or np.inf) * abs(x[b] - x[a - 1])
        if abs(bed[b] - bed[a - 1]) <= reach:
            out[a:b] = np.interp(x[a:b], [x[a - 1], x[b]], [bed[a - 1], bed[b]])
    return out


def _in_runs(held: np.ndarray) -> np.ndarray:
    """Whether the held readings of each wide window (DEEPER_HALF) come in runs, fewer than
    independent pings would make (the Wald-Wolfowitz runs test, one-sided, at ALPHA): a sounder that
    locks and unlocks holds the bottom for a while and loses it for a while; false echoes over a
    bottom it holds strike ping by ping, however many they are."""
    kernel = np.ones(2 * DEEPER_HALF + 1)
    n = np.convolve(np.ones(len(held)), kernel, "same")
    n1 = np.convolve(held.astype(float), kernel, "same")
    n2 = n - n1
    change = np.r_[False, held[1:] != held[:-1]].astype(float)
    r = 1.0 + np.convolve(change, np.r_[0.0, np.ones(2 * DEEPER_HALF)], "same")
    mu = 2 * n1 * n2 / np.maximum(n, 1) + 1
    var = 2 * n1 * n2 * (2 * n1 * n2 - n) / np.maximum(n**2 * (n - 1), 1)
    with np.errstate(all="ignore"):
        z = (r - mu) / np.sqrt(var)
    return (n1 == 0) | (n2 == 0) | (np.nan_to_num(z, nan=0.0) < norm.ppf(ALPHA))


def _joined(lost: np.ndarray) -> np.ndarray:
    """Lost stretches less than a window apart joined: where the share held swings about a half
    within a window, the bottom is not back."""
    out = lost.copy()
    edges = np.flatnonzero(np.diff(np.r_[0, lost.astype(int), 0]))
    for a, b in zip(edges[1:-1:2], edges[2::2], strict=True):  # each gap between two stretches
        if b - a <= 2 * HALF + 1:
            out[a:b] = True
    return out


def _bridges(d: np.ndarray, lay: Layers, held: np.ndarray) -> np.ndarray:
    """The readings between two held ones at different depths (beyond their bands) that a seabed joins
    to both: every step of the chain, from the held reading before through them to the held one
    after, within the readings' bands and what a bed can climb or fall over the distance (max_slope;
    against time, none is joined). A short steep stretch between two levels (a channel's wall crossed in a few
    pings, too short and bent for a layer of its own) is bed; between two readings of one level, a
    reading off the layers is not (a spike goes and comes back), and a false bottom or a second echo
    steps beyond a bed's reach."""
    out = np.zeros(len(d), bool)
    if lay.max_slope <= 0:  # against time no reach is known
        return out
    slope, band, x = lay.max_slope, K * lay.sd, lay.x
    edges = np.flatnonzero(np.diff(np.r_[0, (~held).astype(int), 0]))
    for a, b in zip(edges[::2], edges[1::2], strict=True):  # not held from a to b - 1
        if a == 0 or b == len(d):
            continue
        k = np.arange(a - 1, b + 1)
        step, noise = np.diff(d[k]), band[k[1:]] + band[k[:-1]]
        with np.errstate(invalid="ignore"):
            reach = noise + slope * np.abs(np.diff(x[k]))
        if abs(d[b] - d[a - 1]) > noise[0] + noise[-1] and np.all(np.abs(step) <= reach):
            out[a:b] = True
    return out


def _cut_off(d: np.ndarray, lay: Layers, held: np.ndarray) -> np.ndarray:
    """The runs of held readings that no seabed joins to a deeper held run beside them, and that lie
    above the runs on both sides (or on the one side a run at either end of the log has): where the
    step from the last reading of one run to the first of the next exceeds their bands and what a bed
    can climb or fall over the distance between them (CUT_SLOPE), a run shallower than both
    neighbours is no bottom (nothing echoes from below the bottom: a sounder's ringing, a plateau
    between its glides to the depth). A wall climbs one way: the run below it is the bed. Against time
    (no slope known), none is cut."""
    cut = np.zeros(len(d), bool)
    if lay.max_slope <= 0:
        return cut
    x, band = lay.x, K * lay.sd
    jump = np.r_[False, np.abs(np.diff(d)) > band[1:] + band[:-1] + lay.max_slope * np.diff(x)]
    slope = min(lay.max_slope, CUT_SLOPE)
    for _ in range(4):  # a run cut off uncovers its neighbours' step; a few rounds settle it
        keep = held & ~cut
        # runs of held readings, split where one steps beyond reach of the one before
        joined = np.r_[False, keep[:-1] & keep[1:] & ~jump[1:]]  # continues the one before
        first = np.flatnonzero(keep & ~joined)
        last = np.flatnonzero(keep & ~np.r_[joined[1:], False])
        if len(first) < 2:
            break
        a, b = last[:-1], first[1:]  # the step from each run to the next
        step = d[b] - d[a]
        allowed = band[a] + band[b] + slope * np.abs(x[b] - x[a])
        beyond_after = np.r_[step > allowed, False]  # the next run deeper, beyond a bed's reach
        beyond_before = np.r_[False, step < -allowed]  # the run before deeper, beyond its reach
        deeper_after = np.r_[step > 0, True]  # (no run after: nothing says it is not the bottom)
        deeper_before = np.r_[True, step < 0]
        pit = (beyond_after & deeper_before) | (beyond_before & deeper_after)
        if not pit.any():
            break
        for r in np.flatnonzero(pit):
            cut[first[r] : last[r] + 1] = True
    return cut


def judge(d: np.ndarray, x: np.ndarray, along_track: bool) -> Judged:
    """Every reading's reason (``d`` finite readings in time order; ``x`` metres travelled when
    ``along_track``, else seconds)."""
    n = len(d)
    lay = layers(d, x, along_track)
    bed, starts = np.full(n, np.nan), np.zeros(n, int)
    for a in range(0, n, BLOCK // 4):
        rows = np.arange(a, min(n, a + BLOCK // 4))
        bed[rows], starts[rows] = _bed_block(d, lay, rows)
    bed = _bridged(bed, lay)
    band = K * lay.sd
    held = np.abs(d - bed) <= band
    echo = np.abs(d - 2.0 * bed) <= band * ECHO_SD
    # the bottom is seen where the sounder reads it, or its second echo (which says where it is)
    kernel = np.ones(2 * HALF + 1)
    share = np.convolve(held | echo, kernel, "same") / np.convolve(np.ones(n), kernel, "same")
    lost_region = _joined(~np.isfinite(bed) | ((share < 0.5) & _in_runs(held | echo)))
    # inside a lost stretch a run of held readings is kept where other runs of its window hold the
    # same bed (it continues the bed seen before or after it): one run alone is a sounder stuck on
    # its own ringing, or gliding, as well as a bottom
    held &= ~lost_region | (lay.on & (starts >= 2))
    held |= _bridges(d, lay, held) & ~lost_region
    held &= ~_cut_off(d, lay, held)
    reason = np.full(n, SPIKE)
    reason[lost_region] = LOST
    reason[lay.on & (d < bed - band)] = FALSE_BOTTOM  # a layer of its own, above the bed
    reason[echo] = SECOND_ECHO
    reason[held] = HELD
    return Judged(lay, bed, reason, lost_region, share)


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """The runs of True: (first, last) index of each."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2] - 1, strict=True)]


@dataclass
class Stretch:
    """One stretch where the sounder lost the bottom: readings ``i0`` to ``i1`` (inclusive), their
    rows ``r0`` to ``r1``, seconds since the start ``t0`` to ``t1``, and the share of them held."""

    i0: int
    i1: int
    r0: int
    r1: int
    t0: float
    t1: float
    held: float

    @property
    def n(self) -> int:
        return self.i1 - self.i0 + 1

    def text(self) -> str:
        return f"{self.t0 / 60:.1f}-{self.t1 / 60:.1f} min ({self.n} soundings, {self.held:.0%} held)"


@dataclass
class Soundings:
    """A column of soundings judged: per reading (its first row ``first``; ``group``: each row's
    reading) its reason (-1: no sounding), the bed and its sd, and the lost stretches."""

    group: np.ndarray
    first: np.ndarray
    reason: np.ndarray
    bed: np.ndarray
    sd: np.ndarray
    stretches: list[Stretch]

    @property
    def row_reasons(self) -> np.ndarray:
        """Per row: its reading's reason (-1 where there is no sounding)."""
        return self.reason[self.group]


def _along(trel: np.ndarray, xy: np.ndarray | None) -> tuple[np.ndarray, bool]:
    """Where each reading lies along the track: metres travelled where most have a position, else
    seconds."""
    if xy is None or np.isfinite(xy).all(axis=1).mean() < 0.5:
        return np.asarray(trel, float), False
    step = np.hypot(*np.diff(np.asarray(xy, float), axis=0).T)
    return np.r_[0.0, np.cumsum(np.nan_to_num(step))], True


def judge_column(depth: np.ndarray, trel: np.ndarray, xy: np.ndarray | None = None) -> Soundings:
    """The soundings of a table's column judged (one per row, NaN where none; ``trel`` each row's
    time in seconds, ``xy`` its position in metres): rows that repeat the sounder's reading grouped
    into one (forcemap.host.fuse.bottom_lost.readings_of), each reading's reason, the stretches."""
    group = readings_of([depth])
    first = np.flatnonzero(np.diff(group, prepend=-1))
    d = depth[first]
    reason = np.where(np.isfinite(d), HELD, -1)
    bed, sd, region = np.full(len(d), np.nan), np.full(len(d), np.nan), np.zeros(len(d), bool)
    idx = np.flatnonzero(np.isfinite(d))
    x, along = _along(trel[first], None if xy is None else xy[first])
    if len(idx) > 2 * HALF:  # fewer than a window of readings: nothing to judge them against
        j = judge(d[idx], x[idx], along)
        reason[idx], bed[idx], sd[idx], region[idx] = j.reason, j.bed, j.layers.sd, j.lost_region
    t, stretches = trel[first], []
    for a, b in runs(region[idx]):
        i0, i1 = int(idx[a]), int(idx[b])
        r1 = int(np.flatnonzero(group == i1)[-1])
        held = float(np.mean(reason[idx[a] : idx[b] + 1] == HELD))
        stretches.append(Stretch(i0, i1, int(first[i0]), r1, float(t[i0]), float(t[i1]), held))
    return Soundings(group, first, reason, bed, sd, stretches)
