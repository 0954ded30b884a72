"""Which layer is the bottom, and why every other sounding is rejected: held, the bottom lost, a spike, a
false bottom, a second echo.

The layers come from forcemap.host.fuse.smooth_bed (through each reading, the bed its neighbours
support). At each reading, the bed is chosen among the layers of its window by physics:

- echoes come from above the bottom, never from below it, except its multiples: the bed is the deepest
  layer that is not at twice another's depth (a second echo, the pulse reflected by the surface and
  the bottom again);
- a sounder that holds a bottom does not read deeper than it: where more readings of the window lie
  deeper than a layer (and not at twice its depth) than on it, that layer is no bottom (a thermocline,
  a school of fish: a false bottom), and the window has none.

A reading within K sd of the bed is held. The sounder holds the bottom where most readings of the
window are held; elsewhere (fewer, or no bed at all) it has lost it, and the runs of such readings are
the lost stretches. Inside them a run of readings that lines up with the bed its neighbours support is
held, and kept: it continues the bed seen around it. Every other reading is rejected, for one reason:

| code | reason | the reading |
|---:|---|---|
| 0 | held | on the bed |
| 1 | lost_bottom | in a lost stretch, on no layer |
| 2 | spike | where the bottom is held, off it and on no layer of its own |
| 3 | false_bottom | on a layer of its own above the bed (or where there is no bed) |
| 4 | second_echo | at twice the bed's depth |

Rows are never dropped: the import marks them (the samples' ``bottom_lost`` column carries the code),
and depth maps leave out every row whose code is not 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
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
    """Whether each candidate layer ``j`` of a row has no more readings deeper than it than on it, over
    the wider window (DEEPER_HALF): deeper beyond its band and beyond what a bed could descend
    (max_slope) between its nearest reading and them, and not at twice its depth. A steep bed's far
    side is no evidence against it; a sounder's ringing between glides to the depth is."""
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
    deeper = wvalid[:, None, :] & (dk > line + band + lay.max_slope * gap) & ~echo
    return deeper.sum(axis=2) <= won.sum(axis=2)


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
    against time, any). A short steep stretch between two levels (a channel's wall crossed in a few
    pings, too short and bent for a layer of its own) is bed; between two readings of one level, a
    reading off the layers is not (a spike goes and comes back), and a false bottom or a second echo
    steps beyond a bed's reach."""
    out = np.zeros(len(d), bool)
    slope = lay.max_slope if lay.max_slope > 0 else np.inf
    band, x = K * lay.sd, lay.x
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
    can climb or fall over the distance between them (max_slope), a run shallower than both
    neighbours is no bottom (nothing echoes from below the bottom: a sounder's ringing, a plateau
    between its glides to the depth). A wall climbs one way: the run below it is the bed. Against time
    (no slope known), none is cut."""
    cut = np.zeros(len(d), bool)
    if lay.max_slope <= 0:
        return cut
    for _ in range(4):  # a run cut off uncovers its neighbours' step; a few rounds settle it
        edges = np.flatnonzero(np.diff(np.r_[0, (held & ~cut).astype(int), 0]))
        first, last = edges[::2], edges[1::2] - 1
        if len(first) < 2:
            break
        a, b = last[:-1], first[1:]  # the step from each run to the next
        step = d[b] - d[a]
        allowed = K * (lay.sd[a] + lay.sd[b]) + lay.max_slope * np.abs(lay.x[b] - lay.x[a])
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
    reason[lay.on & ~(d > bed + band)] = FALSE_BOTTOM  # a layer of its own, above the bed or none
    reason[echo] = SECOND_ECHO
    reason[held] = HELD
    return Judged(lay, bed, reason, lost_region, share)


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """The runs of True: (first, last) index of each."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2] - 1, strict=True)]
