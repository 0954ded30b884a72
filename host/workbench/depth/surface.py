"""The depth surface most soundings support: each sounding with its TVU propagated to grid nodes, several
depth hypotheses kept per node where the soundings disagree, the one with the most soundings chosen.

It follows CUBE (Calder & Mayer 2003, "Automatic processing of high-rate, high-density multibeam
echosounder data"), the surface CARIS HIPS and QPS Qimera build, in a form a single-beam survey needs:

- every sounding that is not a spike and not in a stretch where the bottom was lost
  (forcemap.host.workbench.survey.spikes) reaches the nodes within CAPTURE cells of it, with its variance grown
  by the distance: ``sd_node^2 = sd^2 + (slope x (distance + sd_h))^2`` (the bed's slope along the track
  carries a sounding's depth to a neighbouring node as badly as it carries a position error);
- at each node the soundings are taken in time order; each joins the hypothesis whose depth it is
  nearest in units of their combined sd, if within GATE of it (a Kalman update: inverse-variance
  mean), else it starts a new hypothesis. A false echo or a second bottom becomes a hypothesis of its
  own and never pulls the true bed toward it;
- the node's depth is the hypothesis most soundings support (CUBE's "number of samples"
  disambiguation); ties go to the smaller variance.

A node's uncertainty is a sounding's there (the harmonic mean of its chosen soundings' propagated
variances: the nearest count most), not the sd of their mean: the soundings' errors share their sources
(the sounder's calibration, the attitude, the position), and averaging hides none of that. Its TVU is 1.96 times that, graded against
IHO S-44 (forcemap.host.fuse.tvu). A node no sounding reaches is empty: no cell is made from a lost
stretch or from extrapolation (the GP map, forcemap.host.workbench.targets.target_model, is the continuous estimate).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from forcemap.host.fuse import tvu
from forcemap.host.workbench.survey.table import Survey

CAPTURE = 1.5  # cells: a sounding reaches the nodes within this many cell sizes of it
GATE = 3.0  # a sounding joins a hypothesis within this many combined sds of its depth


@dataclass
class Surface:
    """Per node (flat, in the order given): the chosen hypothesis and what supports it."""

    depth: np.ndarray
    sd: np.ndarray  # 1 sd, m
    hypotheses: np.ndarray  # how many the node kept
    soundings: np.ndarray  # how many reached it
    support: np.ndarray  # the share of them in the chosen hypothesis

    @property
    def tvu(self) -> np.ndarray:
        return tvu.Z95 * self.sd

    def order(self) -> np.ndarray:
        """The strictest S-44 order each node's TVU meets (tvu.ORDER_CODES; 0 none; NaN empty)."""
        code = tvu.order_met(self.tvu, self.depth).astype(float)
        return np.where(code < 0, np.nan, code)


def survey_soundings(survey: Survey, position_sd: float = tvu.POSITION_SD_M) -> dict:
    """The soundings the surface is built from: the depth column's rows that are not spikes or lost
    (one per reading), with their TVU's sd, the bed's slope along the track between them, their local
    scatter and time, and each row's reading among them."""
    from forcemap.host.fuse.bottom_lost import readings_of
    from forcemap.host.workbench.survey.spikes import target_spikes

    depth = survey.columns["depth"]
    keep = np.isfinite(depth)
    if "depth" not in survey.spikes_removed and not survey.keep_outliers:
        found = target_spikes(survey, "depth")  # a survey whose spikes are still in it
        if found is not None:
            keep &= ~found.flagged
    # a table sampled faster than its sounder holds a reading over several rows: one sounding (where
    # most rows repeat the one before, as the spike test counts readings; a coarse sounder over a flat
    # bed repeats its value too, reading after reading, and each is a sounding)
    group = readings_of([depth])
    held = np.r_[False, (group[1:] == group[:-1]) & keep[1:] & keep[:-1]]
    reading = np.where(keep, np.cumsum(keep & ~held) - 1, -1)  # a held row is its reading's
    keep &= ~held
    cols = survey.columns
    slope = bed_slope(depth[keep], survey.xy[keep], position_sd)
    att = tvu.attitude_sd(depth, cols.get("depth_raw"), cols.get("roll"), cols.get("pitch"))[keep]
    sd = tvu.sounding_tvu(depth[keep], tvu.SounderSpec(), att, slope, position_sd).sd
    given = cols.get("depth_tvu")  # the export's, from the log's own sounder and position noise
    if given is not None:
        sd = np.where(np.isfinite(given[keep]), given[keep] / tvu.Z95, sd)
    return {
        "xy": survey.xy[keep],
        "depth": depth[keep],
        "sd": sd,
        "scatter": local_scatter(depth[keep]),
        "slope": slope,
        "t": cols["t"][keep],
        "position_sd": position_sd,
        "reading": reading,  # per row of the survey: its sounding here (-1: none)
    }


def bed_slope(depth: np.ndarray, xy: np.ndarray, base: float) -> np.ndarray:
    """The bed's slope (m/m) at each sounding (in time order): the change in depth to the first sounding
    at least ``base`` metres further along the track (back from the track's end), the median over
    tvu.SLOPE_WINDOW soundings. From the soundings the surface uses, over a baseline a position error
    spans: a held row, an echo or a sounding 0.5 m from the last is no measure of the bed's slope."""
    from forcemap.host.fuse.bottom_lost import running

    n = len(depth)
    if n < 2:
        return np.zeros(n)
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]
    ahead = np.searchsorted(s, s + base)
    other = np.where(ahead < n, ahead, np.searchsorted(s, s - base, side="right") - 1)
    ds = np.abs(s[np.maximum(other, 0)] - s)
    raw = np.where(
        (other >= 0) & (ds > 0),
        np.abs(depth[np.maximum(other, 0)] - depth) / np.maximum(ds, 1e-9),
        np.nan,
    )
    return np.clip(np.nan_to_num(running(raw, tvu.SLOPE_WINDOW, np.nanmedian)), 0.0, 1.0)


def local_scatter(depth: np.ndarray) -> np.ndarray:
    """Each sounding's local scatter (1 sd, m): 1.4826 x the median absolute departure from the running
    median of the spike test's WINDOW soundings along the track, over its SCALE_WINDOW soundings (what the
    sounder does there, which its stated accuracy may understate: heave, a coarse resolution, waves)."""
    from forcemap.host.fuse.bottom_lost import running
    from forcemap.host.workbench.survey.spikes import MAD_TO_STD, SCALE_WINDOW, WINDOW

    if not len(depth):
        return np.zeros(0)
    departure = np.abs(depth - running(depth, WINDOW, np.nanmedian))
    return MAD_TO_STD * running(departure, SCALE_WINDOW, np.nanmedian)


def build(nodes: np.ndarray, s: dict, cell: float) -> Surface:
    """The surface at ``nodes`` (n, 2 metres in the survey frame) from ``survey_soundings``."""
    from scipy.spatial import cKDTree

    n = len(nodes)
    out = Surface(
        np.full(n, np.nan), np.full(n, np.nan), np.zeros(n), np.zeros(n), np.full(n, np.nan)
    )
    if not len(s["depth"]) or not n:
        return out
    order = np.argsort(s["t"], kind="stable")
    xy, z, sd, slope = s["xy"][order], s["depth"][order], s["sd"][order], s["slope"][order]
    reach = cKDTree(nodes).query_ball_point(xy, CAPTURE * cell)
    lens = np.fromiter((len(r) for r in reach), int, len(reach))
    if not lens.sum():
        return out
    node = np.concatenate([np.asarray(r, int) for r in reach if len(r)])
    snd = np.repeat(np.arange(len(z)), lens)
    dist = np.hypot(*(nodes[node] - xy[snd]).T)
    var = sd[snd] ** 2 + (slope[snd] * (dist + s["position_sd"])) ** 2
    by = np.lexsort((snd, node))  # per node, in time order
    node, snd, var = node[by], snd[by], var[by]
    starts = np.flatnonzero(np.diff(np.r_[-1, node]))
    ends = np.r_[starts[1:], len(node)]
    for a, b in zip(starts, ends, strict=True):
        k = node[a]
        best = _node(z[snd[a:b]], var[a:b])
        out.depth[k], out.sd[k], out.hypotheses[k], out.soundings[k], out.support[k] = best
    return out


def _node(z: np.ndarray, var: np.ndarray) -> tuple[float, float, int, int, float]:
    """One node's hypotheses from its soundings in time order: (depth, sd, hypotheses, soundings,
    support) of the one most soundings support."""
    h = hypotheses(z, var)
    j, count = h.chosen, h.count
    total = len(z)
    return h.mean[j], (count[j] / h.own[j]) ** 0.5, len(h.mean), total, count[j] / total


@dataclass
class Hypotheses:
    """One node's hypotheses: each one's depth, the variance of that depth, its soundings' count and
    the sum of their inverse variances; which one each sounding joined, and the one chosen."""

    mean: list[float]
    post: list[float]
    count: list[int]
    own: list[float]
    member: list[int]  # per sounding, in the order given

    @property
    def chosen(self) -> int:
        """The hypothesis most soundings support (ties: the smaller variance)."""
        return max(range(len(self.mean)), key=lambda h: (self.count[h], -self.post[h]))


def hypotheses(z: np.ndarray, var: np.ndarray) -> Hypotheses:
    """A node's soundings (in time order, their propagated variances) sorted into hypotheses: each joins
    the one whose depth it is nearest in units of their combined sd, within GATE (a Kalman update), or
    starts its own."""
    out = Hypotheses([], [], [], [], [])
    mean, post, count, own = out.mean, out.post, out.count, out.own
    for zi, vi in zip(z.tolist(), var.tolist(), strict=True):
        j, score = -1, GATE
        for h in range(len(mean)):
            s = abs(zi - mean[h]) / (vi + post[h]) ** 0.5
            if s <= score:
                j, score = h, s
        if j < 0:
            out.member.append(len(mean))
            mean.append(zi)
            post.append(vi)
            count.append(1)
            own.append(1.0 / vi)
            continue
        out.member.append(j)
        w = post[j] / (post[j] + vi)
        mean[j] += w * (zi - mean[j])
        post[j] = post[j] * vi / (post[j] + vi)
        count[j] += 1
        own[j] += 1.0 / vi
    return out
