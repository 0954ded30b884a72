"""The season's model, fitted from the logs' sufficient statistics alone.

- depth: one static map over every survey (const + Matern 3/2 GP in position);
- current: one spatial shape (east and north, const + GP) times a per-survey scale s_k (the discharge),
  normalised to mean 1; with a per-survey offset per component when the evidence asks for it (BIC);
- wind: a map per survey on a coarse basis (it changes by the day), its hyperparameters from that survey,
  fitted where the log is read (`tasks.fit_wind`).

The scales and the shape are fitted by alternation: given the scales, the shape's hyperparameters and weights
come from the scaled, summed statistics (sum s_k^2 G_k, sum s_k B_k); given the shape, each s_k is a
least-squares ratio of survey k's own statistics. Hyperparameters are fitted on the statistics of the
hyperparameter rows (one sample every 5 s, as a single survey's fit does), the maps on all rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.season.stats import (
    Posterior,
    Prior,
    Stats,
    fit_hypers,
    posterior,
    target_scale,
    tree_sum,
    weighted_sum,
    without_offset,
)
from forcemap.host.season.tasks import Frame, SurveyResult

MAX_ROUNDS = 200
HYPER_ROUNDS = 3
SCALE_TOL = 1e-8


@dataclass
class StaticFit:
    """The depth map: hyperparameters, the summed statistics and the posterior; with `levels`, the depth of
    survey k is the static bed plus its water level levels[k] (centred on the season's mean, sd level_sd[k]),
    and `total` holds the statistics with each survey's level profiled out (`without_offset`)."""

    prior: Prior
    theta: np.ndarray
    total: Stats
    y_scale: float
    post: Posterior
    log_evidence: float
    levels: np.ndarray | None = None
    level_sd: np.ndarray | None = None
    levels_evidence_gain: float = 0.0  # log evidence with a level per survey minus without
    paths: list[str] = field(default_factory=list)  # the surveys with depth, in the order of levels


@dataclass
class CurrentFit:
    """The current's shared shape (east, north weights at scale 1), the per-survey scales and offsets."""

    prior: Prior
    theta: np.ndarray
    y_scale: float
    post: Posterior
    scales: np.ndarray
    offsets: np.ndarray  # (K, 2), zeros without offsets
    with_offsets: bool
    log_evidence: float
    rounds: int
    evidence_gain: float = 0.0  # log evidence with offsets minus without
    own: list[np.ndarray] = field(
        default_factory=list
    )  # each survey's own map's weights (season hyperparameters)


def fit_depth(
    frame: Frame, total: dict, results: list[SurveyResult], levels: bool | None = None
) -> StaticFit | None:
    """The static bed, and with `levels` (True / False, or None to let the evidence decide, BIC as for the
    current's offsets) one water level per survey fitted with it: a sounder measures from the moving surface,
    so a season whose stage follows the discharge sees the same bed deeper in a flood."""
    use = [r for r in results if r.has["depth"]]
    if not use:
        return None
    prior = Prior(frame.space)
    full, hyper = total["depth"], total["depth_hyper"]
    if len(use) < len(results):
        full = tree_sum([r.stats["depth"] for r in use])
        hyper = tree_sum([r.stats["depth_hyper"] for r in use])
    y_scale = float(target_scale(full)[0])
    theta, logp = fit_hypers(prior, hyper, y_scale)
    fit = StaticFit(prior, theta, full, y_scale, posterior(prior, theta, full, y_scale), logp)
    fit.paths = [r.path for r in use]
    if len(use) < 2 or levels is False:
        return fit
    each = [r.stats["depth"] for r in use]
    lfull = tree_sum([without_offset(st) for st in each])
    lhyper = tree_sum([without_offset(r.stats["depth_hyper"]) for r in use])
    ltheta, llogp = fit_hypers(prior, lhyper, y_scale, theta)
    gain = llogp - logp
    fit.levels_evidence_gain = float(gain)
    if levels is None and not gain > len(use) * math.log(max(hyper.n, 2)):
        return fit
    post = posterior(prior, ltheta, lfull, y_scale)
    lv, sd = survey_levels(post, each)
    # the bed at the season's mean level: the profiled constant goes to the map, the levels are centred
    post.mean[0, 0] += float(lv.mean())
    return StaticFit(
        prior, ltheta, lfull, y_scale, post, llogp, lv - lv.mean(), sd, float(gain), fit.paths
    )


def survey_levels(post: Posterior, each: list[Stats]) -> tuple[np.ndarray, np.ndarray]:
    """Each survey's level given the bed `post` (its mean residual depth) and its sd: the sounder's noise
    over the survey's samples and the bed's own uncertainty averaged over its track (the sd of the level
    against the season's mean: the bed's constant cancels)."""
    W = post.mean
    lv = np.array([(st.B[0, 0] - st.G[0] @ W[:, 0]) / max(st.n, 1) for st in each])
    g = np.array([st.G[0] / max(st.n, 1) for st in each])
    # a centred level's bed term is the survey's track mean less the season's: what is common cancels
    g = g - g.mean(axis=0)
    _, bed_sd = post.predict(g)
    noise2 = post.sn2 * post.y_scale**2
    return lv, np.sqrt(bed_sd**2 + noise2 / np.array([max(st.n, 1) for st in each]))


def _scaled_sum(stats: list[Stats], s: np.ndarray) -> Stats:
    return weighted_sum(stats, s)


def _alternate(prior: Prior, full: list[Stats], hyper: list[Stats], y_scale: float):
    """Shape and scales by alternation until the scales stop moving. The hyperparameters follow the scales
    for the first HYPER_ROUNDS rounds (they settle at once) and once more at the end."""
    s, theta, logp, prev = np.ones(len(full)), None, -math.inf, None
    for rounds in range(1, MAX_ROUNDS + 1):
        if rounds <= HYPER_ROUNDS:
            theta, logp = fit_hypers(prior, _scaled_sum(hyper, s), y_scale, theta)
        W = posterior(prior, theta, _scaled_sum(full, s), y_scale).mean
        num = np.array([np.sum(W * st.B) for st in full])
        den = np.array([np.sum(W * (st.G @ W)) for st in full])
        new = num / np.maximum(den, 1e-300)
        new = new / new.mean()
        step = new - s
        done = np.max(np.abs(step)) < SCALE_TOL
        if prev is not None and rounds > HYPER_ROUNDS + 1 and not done:
            # the alternation converges linearly (rate ~0.9: shape and scale trade off against the prior);
            # Aitken's extrapolation along the step jumps to the limit of that geometric series
            rho = float(step @ prev) / float(prev @ prev)
            if 0.0 < rho < 0.99:
                new = new + step * rho / (1.0 - rho)
                new = new / new.mean()
            step = None
        prev, s = step, new
        if done and rounds > HYPER_ROUNDS:
            break
    theta, logp = fit_hypers(prior, _scaled_sum(hyper, s), y_scale, theta)
    post = posterior(prior, theta, _scaled_sum(full, s), y_scale)
    return theta, logp, post, s, rounds


def fit_current(
    frame: Frame, results: list[SurveyResult], offsets: bool | None
) -> CurrentFit | None:
    """`offsets`: True / False, or None to let the evidence decide (BIC: a gain above p/2 log n)."""
    use = [r for r in results if r.has["current_east"] and r.has["current_north"]]
    if not use:
        return None
    full = [r.stats["current"] for r in use]
    hyper = [r.stats["current_hyper"] for r in use]
    # the targets' scale needs only the const row of B, R and n: summed without the m x m Gram matrices
    light = [Stats(st.G[:1, :1], st.B[:1], st.R, st.n) for st in full]
    y_scale = float(np.mean(target_scale(tree_sum(light))))
    prior = Prior(frame.space)
    fits = {}
    for flag in [False, True] if offsets is None else [offsets]:
        f, h = (
            ([without_offset(st) for st in full], [without_offset(st) for st in hyper])
            if flag
            else (full, hyper)
        )
        fits[flag] = _alternate(prior, f, h, y_scale) + (f,)
    gain = fits[True][1] - fits[False][1] if len(fits) == 2 else 0.0
    n_hyper = sum(st.n for st in hyper)
    chosen = offsets if offsets is not None else bool(gain > len(use) * math.log(n_hyper))
    theta, logp, post, s, rounds, used = fits[chosen]
    off = np.zeros((len(use), 2))
    if chosen:
        for k, st in enumerate(full):
            off[k] = (st.B[0] - s[k] * (st.G[0] @ post.mean)) / max(st.n, 1)
    # the weights only: the staleness needs no more, and a factor per survey is m x m each
    own = [posterior(prior, theta, st, y_scale).mean for st in full]
    return CurrentFit(prior, theta, y_scale, post, s, off, chosen, logp, rounds, gain, own)
