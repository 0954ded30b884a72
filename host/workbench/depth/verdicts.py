"""Each sounding judged by the depth surface at its nearest node, on its own pass there.

The nodes are a lattice ``cell`` metres apart; a node takes the soundings within CAPTURE cells of it
(forcemap.host.workbench.depth.surface), its variance grown by the bed's slope times the distance. Its
soundings are split into passes (PASS_GAP_S apart in time: another pass may read another water level,
and a tide must not outvote a pass), and each pass's soundings are sorted into hypotheses in time order
(`surface.hypotheses`: each joins the depth it is within GATE combined sds of, or starts its own).

A pass is sure of its depth when it holds one hypothesis of two soundings or more. A pass in doubt takes
the hypothesis nearest its locale's guide (CUBE's "locale" disambiguation: the median depth of the
LOCALE nearest sure passes over other nodes), else the one most soundings support. A sounding is then
rejected (`accepted.WHY`) when

- it joined another hypothesis than the chosen one: ALONE if that one holds it alone, else OUTVOTED;
- the chosen hypothesis holds it alone among others and its locale does not vouch for it (ALONE);
- the chosen hypothesis lies farther from the guide than the bed can reach, the seabed path's floor
  (0.5 m + 5 %) plus WALL (1 in 1) times the guide's distance (UNREACHED: a short run of false
  echoes that is the majority of its own pass, the soundings around it flagged as spikes);
- it departs from the chosen depth of the others of its hypothesis by more than 1.96 combined sds
  (BEYOND_TVU: more than its TVU allows).

Most passes hold one hypothesis whose soundings all lie within GATE sds of one another: those are
judged in numpy at once (their hypothesis is the inverse-variance mean of all of them, which is what
the sequential Kalman updates give), the others one by one.
"""

from __future__ import annotations

import numpy as np
from forcemap.host.fuse import tvu
from forcemap.host.fuse.bottom_lost import _nanmedian_rows, path_tolerance
from forcemap.host.workbench.depth.surface import CAPTURE, GATE, hypotheses

LOCALE = 8  # the sure passes whose median guides a pass (CUBE's locale)
PASS_GAP_S = 60.0  # soundings of a node this far apart in time are two passes
WALL = 1.0  # the steepest bed (1 in 1, 45 deg) between a pass and its locale
ALONE, OUTVOTED, BEYOND_TVU, UNREACHED = 1, 2, 3, 4  # why a sounding is rejected (0: accepted)
_REACH = 2  # lattice offsets a node within CAPTURE cells can be at


def verdicts(s: dict, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Each sounding of ``s`` (`surface.survey_soundings`) judged on nodes ``cell`` m apart: why it is
    rejected (0 accepted) and the depth chosen on its pass at its nearest node."""
    order = np.argsort(s["t"], kind="stable")
    z, t = s["depth"][order], s["t"][order]
    var0 = (
        np.fmax(s["sd"], s["scatter"])[order] ** 2
    )  # its TVU, or the soundings' own scatter there
    snd, node, var, near, where = _pairs(
        s["xy"][order], s["slope"][order], var0, cell, s["position_sd"]
    )
    new = np.r_[True, (node[1:] != node[:-1]) | (np.diff(t[snd]) > PASS_GAP_S)]
    start = np.flatnonzero(new)
    p = _Passes(z[snd], var, start)
    guide, far = _locale(where[node[start]], p.sure, p.depth, cell)
    p.choose(guide)
    # its own variance, where it was read: the TVU's (or the scatter's) and a position error on the slope
    own = var0[snd] + (s["slope"][order][snd] * s["position_sd"]) ** 2
    p.plane(s["xy"][order][snd] - where[node], own)
    mine = node == near[snd]  # each sounding on its pass at its nearest node
    unit = (np.cumsum(new) - 1)[mine]
    reason = p.judge(np.flatnonzero(mine), unit, guide[unit], far[unit])
    out, depth = np.zeros(len(z), int), np.full(len(z), np.nan)
    out[order[snd[mine]]], depth[order[snd[mine]]] = reason, p.mean_j[unit]
    return out, depth


def _pairs(xy, slope, var0, cell: float, position_sd: float):
    """Every (sounding, node) within CAPTURE cells, sorted by node then time, the sounding's variance
    there; each sounding's nearest node and the nodes' positions."""
    key = np.round(xy / cell).astype(np.int64)
    nodes, near = np.unique(key, axis=0, return_inverse=True)
    near = near.ravel()
    span = np.arange(-_REACH, _REACH + 1)
    off = np.stack(np.meshgrid(span, span, indexing="ij"), axis=-1).reshape(-1, 2)
    cand = key[:, None, :] + off[None, :, :]
    dist = np.hypot(*np.moveaxis(xy[:, None, :] - cand * cell, -1, 0))
    snd, which = np.nonzero(dist <= CAPTURE * cell)
    lo = nodes.min(axis=0) - _REACH
    width = int(nodes[:, 1].max() - lo[1]) + 2 * _REACH + 1
    code = (nodes[:, 0] - lo[0]) * width + (nodes[:, 1] - lo[1])  # sorted: np.unique's order
    ck = cand[snd, which]
    c = (ck[:, 0] - lo[0]) * width + (ck[:, 1] - lo[1])
    pos = np.minimum(np.searchsorted(code, c), len(code) - 1)
    ok = code[pos] == c
    snd, node, d = snd[ok], pos[ok], dist[snd[ok], which[ok]]
    var = var0[snd] + (slope[snd] * (d + position_sd)) ** 2
    by = np.lexsort((snd, node))
    return snd[by], node[by], var[by], near, nodes * cell


class _Passes:
    """The passes (runs of ``start``) of the (node, sounding) pairs: their hypotheses, the chosen one."""

    def __init__(self, z: np.ndarray, var: np.ndarray, start: np.ndarray) -> None:
        self.z, self.var, self.start = z, var, start
        self.size = np.diff(np.r_[start, len(z)])
        w = 1.0 / var
        self.W = np.add.reduceat(w, start)
        self.mean = np.add.reduceat(w * z, start) / self.W
        spread = np.maximum.reduceat(z, start) - np.minimum.reduceat(z, start)
        # all within GATE sds of one another: one hypothesis of them all (the Kalman updates' mean)
        simple = spread <= GATE * np.sqrt(np.minimum.reduceat(var, start))
        self.member_count = np.repeat(self.size, self.size)  # the count of the hypothesis joined
        self.chosen = np.ones(len(z), bool)  # the pair's sounding joined the chosen hypothesis
        self.sure = simple & (self.size > 1)
        self.hyps = {}
        for u in np.flatnonzero(~simple):
            a = start[u]
            h = hypotheses(z[a : a + self.size[u]], var[a : a + self.size[u]])
            self.hyps[u] = h
            self.sure[u] = len(h.mean) == 1 and h.count[0] > 1
        self.depth = self.mean.copy()
        for u, h in self.hyps.items():
            self.depth[u] = h.mean[0]
        self.mean_j, self.W_j, self.count_j = self.mean.copy(), self.W.copy(), self.size.copy()

    def choose(self, guide: np.ndarray) -> None:
        """Each pass in doubt's chosen hypothesis: the one nearest its guide, else most supported."""
        for u, h in self.hyps.items():
            j = h.chosen
            if len(h.mean) > 1 and np.isfinite(guide[u]):
                j = int(np.argmin(np.abs(np.asarray(h.mean) - guide[u])))
            a, member = self.start[u], np.asarray(h.member)
            self.member_count[a : a + len(member)] = np.asarray(h.count)[member]
            self.chosen[a : a + len(member)] = member == j
            self.mean_j[u], self.W_j[u], self.count_j[u] = h.mean[j], 1.0 / h.post[j], h.count[j]

    def judge(
        self, pair: np.ndarray, unit: np.ndarray, guide: np.ndarray, far: np.ndarray
    ) -> np.ndarray:
        """The verdicts of the soundings of ``pair`` (each on its pass ``unit``)."""
        chosen, count = self.chosen[pair], self.member_count[pair]
        out = np.where(count == 1, ALONE, OUTVOTED)
        known = np.isfinite(guide)
        off = np.where(known, np.abs(self.mean_j[unit] - guide), 0.0)
        tol = np.where(known, path_tolerance(np.nan_to_num(guide)), 0.0)
        unreached = known & (off > tol + WALL * np.nan_to_num(far))
        vouched = (self.count_j[unit] > 1) | (known & (off <= tol)) | (self.size[unit] == 1)
        out[chosen] = np.where(unreached, UNREACHED, np.where(vouched, 0, ALONE))[chosen]
        out[(out == 0) & chosen & self._beyond(pair, unit)] = BEYOND_TVU
        return out

    def plane(self, dxy: np.ndarray, own: np.ndarray) -> None:
        """The weighted sums of each pass's chosen soundings for a plane of depth through them (``dxy``
        metres from the node, ``own`` each sounding's variance where it was read)."""
        self.dxy, self.own = dxy, own
        w = np.where(self.chosen, 1.0 / own, 0.0)
        self.sums = np.add.reduceat(_moments(w, dxy, self.z), self.start, axis=0)

    def _beyond(self, pair: np.ndarray, unit: np.ndarray) -> np.ndarray:
        """Whether each of its pass's chosen soundings departs from the plane the others draw (leave-one-
        out, weighted; its slopes held to a seabed's by a prior of WALL) by more than its TVU allows: 1.96
        sds of the two combined. A plane, not their mean: on a slope the others lie deeper on one side,
        and a pass may turn over the node. Passes of fewer than three chosen soundings are not judged."""
        v, z, dxy = self.own[pair], self.z[pair], self.dxy[pair]
        w = np.where(self.chosen[pair], 1.0 / v, 0.0)
        m = self.sums[unit] - _moments(w, dxy, z)
        A = np.empty((len(pair), 3, 3))
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 2] = m[:, 0], m[:, 1], m[:, 2]
        A[:, 1, 1], A[:, 1, 2], A[:, 2, 2] = m[:, 3], m[:, 4], m[:, 5]
        A[:, 1, 0], A[:, 2, 0], A[:, 2, 1] = m[:, 1], m[:, 2], m[:, 4]
        A[:, 0, 0] += 1e-12
        A[:, 1, 1] += 1.0 / WALL**2
        A[:, 2, 2] += 1.0 / WALL**2
        at = np.column_stack([np.ones(len(pair)), dxy])
        sol = np.linalg.solve(A, np.stack([m[:, 6:9], at], axis=-1))  # coefficients, and A^-1 a
        pred = np.einsum("ij,ij->i", at, sol[..., 0])
        var = np.einsum("ij,ij->i", at, sol[..., 1])
        enough = self.count_j[unit] >= 3
        return enough & (np.abs(z - pred) > tvu.Z95 * np.sqrt(v + var))


def _moments(w: np.ndarray, dxy: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Per sounding: w, w x, w y, w x x, w x y, w y y, w z, w z x, w z y (a weighted plane's sums)."""
    x, y = dxy[:, 0], dxy[:, 1]
    return np.column_stack(
        [w, w * x, w * y, w * x * x, w * x * y, w * y * y, w * z, w * z * x, w * z * y]
    )


def _locale(where: np.ndarray, sure: np.ndarray, depth: np.ndarray, cell: float):
    """Each pass's guide: the median depth of the LOCALE nearest sure passes, itself left out, and their
    median distance, at least a cell (another pass over the same node may read another water level);
    NaN where fewer than two passes are sure."""
    from scipy.spatial import cKDTree

    n, idx_sure = len(where), np.flatnonzero(sure)
    if len(idx_sure) < 2:
        return np.full(n, np.nan), np.full(n, np.nan)
    k = min(LOCALE + 1, len(idx_sure))
    dist, idx = cKDTree(where[idx_sure]).query(where, k=k)
    dist, idx = dist.reshape(n, k), idx.reshape(n, k)
    other = idx_sure[idx] != np.arange(n)[:, None]
    other[other.all(axis=1), -1] = False  # the LOCALE nearest others
    d = np.where(other, depth[idx_sure[idx]], np.nan)
    far = _nanmedian_rows(np.where(other, dist, np.nan))
    return _nanmedian_rows(d), np.fmax(far, cell)
