"""What a survey can tell apart: identifiability of a candidate against position and the model's terms, clocks
and counters as stand-ins for time, and the survey that would separate a confounded candidate.

A term in a covariate can only be told from the map if the covariate varies in a way position (and the
terms already in the model) cannot predict: on one pass over one line, time, any counter, the distance along
the line and often the heading are the same variable. The test: predict the candidate at each held-out block
from the other blocks' positions (and the model's terms), then put that prediction in the candidate's
place. If the stand-in, which knows nothing position elsewhere does not imply, keeps most of the gain, the
gain is position's, and the candidate is confounded with it.
"""

from __future__ import annotations

import numpy as np
from forcemap.host.workbench.engine.model import Model
from forcemap.host.workbench.survey.table import Survey, is_circular
from forcemap.host.workbench.terms.gp import LinearTerm

# a candidate is confounded when its stand-in from position keeps at least this share of its gain
REPLACED_SHARE = 0.5
# a column is a clock or a counter when it steps back against time at most this often (wraps, resets)
MAX_BACKSTEPS = 0.005
# ... and changes at least at this share of the samples (a 1-s clock at 10 Hz still does)
MIN_MOVING = 0.05

# a track is one pass when fewer than this share of its samples have a neighbour, within REVISIT_M, that
# is far along the track from them (a parallel line, a crossing, the same line run again)
MAX_REVISITED = 0.1
REVISIT_M = 20.0
# on one pass, a candidate is a smooth function of the distance along it when a smoother over the map's
# own length scale explains at least this share of its variance
SMOOTH_SHARE = 0.5

SPEED_LIKE = ("sog", "stw", "throttle", "app_wind_speed")
HEADING_LIKE = ("heading", "cog", "crab", "app_wind_angle")


def time_proxies(survey: Survey, names: list[str]) -> list[str]:
    """Columns that only count time: monotone in time up to a rare wrap or reset (at most one step back in
    200), e.g. an instrument's ensemble number, a sequence counter that wraps, a second clock. They carry the
    information `t` carries. A measured quantity steps back and forth with its noise."""
    out = []
    for name in names:
        v = survey.columns.get(name)
        if v is None or is_circular(name):
            continue
        v = v[np.isfinite(v)]  # a counter with gaps still counts time where it reads
        if len(v) < 3:
            continue
        d = np.diff(v)
        moving = d[d != 0]
        if len(moving) < MIN_MOVING * len(d):
            continue
        sign = np.sign(np.median(moving))
        if np.sum(np.sign(moving) != sign) <= MAX_BACKSTEPS * len(d):
            out.append(name)
    return out


def along_track(xy: np.ndarray, step_m: float = 1.0) -> np.ndarray:
    """Distance travelled along the track (m) at each sample; GNSS jitter below `step_m` at a standstill
    adds nothing."""
    s = np.zeros(len(xy))
    anchor, run = xy[0], 0.0
    for i in range(1, len(xy)):
        d = float(np.hypot(*(xy[i] - anchor)))
        if d >= step_m:
            run, anchor = run + d, xy[i]
        s[i] = run
    return s


def is_single_pass(survey: Survey, scale_m: float = REVISIT_M) -> bool:
    """Whether the survey's positions are one curve at the map's length scale: hardly any sample has a
    neighbour within `scale_m` (at least REVISIT_M) that is far from it along the track. Then position,
    time and the distance along the track are one variable."""
    radius = max(REVISIT_M, scale_m)
    key = ("single_pass", survey.n, round(radius, 3))
    if key not in survey.cache:
        from scipy.spatial import cKDTree

        xy = survey.xy
        s = along_track(xy)
        pairs = cKDTree(xy).query_pairs(radius, output_type="ndarray")
        far = pairs[np.abs(s[pairs[:, 0]] - s[pairs[:, 1]]) > 3.0 * radius]
        revisited = np.zeros(len(xy), bool)
        revisited[far.ravel()] = True
        survey.cache[key] = bool(revisited.mean() < MAX_REVISITED and s[-1] > 3.0 * radius)
    return survey.cache[key]


def smooth_along_track(survey: Survey, name: str, values: np.ndarray, scale_m: float) -> float:
    """The share of a candidate's variance (an angle's through its unit vector) that a smoother along the
    track over `scale_m` (the map's length scale) explains: near 1 for a drift, a clock or a counter."""
    s = along_track(survey.xy)
    parts = (
        [np.sin(np.radians(values)), np.cos(np.radians(values))]
        if is_circular(name)
        else [np.asarray(values, float)]
    )
    total = sum(float(np.var(p)) for p in parts)
    if total <= 0:
        return 0.0
    # a Gaussian kernel smoother in s over an even grid of the distance (at most ~2000 steps: a map
    # scale below a 500th of the track is no scale for this)
    step = max(scale_m, float(s[-1]) / 500.0, 1.0) / 4
    grid = np.arange(0.0, s[-1] + step, step)
    resid = 0.0
    for p in parts:
        k = np.clip(np.searchsorted(grid, s), 0, len(grid) - 1)
        sums, counts = np.bincount(k, p, len(grid)), np.bincount(k, None, len(grid))
        w = np.exp(-0.5 * (np.arange(-8, 9) / 2.0) ** 2)  # sd of 2 grid steps = scale_m / 2
        smooth = np.convolve(sums, w, "same") / np.maximum(np.convolve(counts, w, "same"), 1e-12)
        resid += float(np.mean((p - smooth[k]) ** 2))
    return 1.0 - resid / total


def map_length_scale(ev) -> float:
    """The spatial GP's length scale (m) in the current model, or 5 % of the track when it has none."""
    ell = ev.sm.primary.position_lengthscale_
    if ell is not None:
        return ell
    return 0.05 * float(along_track(ev.survey.xy)[-1]) or 10.0


def predict_from_model_inputs(ev, name: str, values: np.ndarray) -> tuple[np.ndarray, float]:
    """Blocked-CV prediction of a candidate from the current model's inputs (its terms: position and the
    covariates already in the model) plus a linear trend over position, and the share of the candidate's
    variance it explains (R^2; an angle's through its unit vector).

    Each block is predicted from the others, the way the diagnosis holds blocks out: what the candidate
    knows at a held-out place beyond what position elsewhere implies. The trend matters on one line, where
    time is a linear function of the distance along it and a GP alone would relax to its mean inside a
    held-out block. The features are the current model's own plus the trend's two columns, so this costs a
    hyperparameter search and the fold solves."""
    p = ev.sm.primary
    trend = LinearTerm(("position",))
    trend.setup(ev.survey.xy)
    design = p.design_.augment(trend.features(ev.survey.xy))
    feat = [t for t in p.terms_ if not t.is_mean]
    parts = (
        [np.sin(np.radians(values)), np.cos(np.radians(values))]
        if is_circular(name)
        else [np.asarray(values, float)]
    )
    preds = []
    for y in parts:
        if np.ptp(y) < 1e-12:
            preds.append(y.copy())
            continue
        m = Model([*feat, trend], hyper_spacing_s=p.hyper_spacing_s)
        m.fit_design(ev.sm.X, y, design)
        preds.append(m.cv_predict(ev.fold_id, return_std=False)[0])
    resid = sum(np.mean((y - q) ** 2) for y, q in zip(parts, preds, strict=True))
    total = sum(np.var(y) for y in parts) or 1.0
    r2 = float(1.0 - resid / total)
    if is_circular(name):
        return np.degrees(np.arctan2(preds[0], preds[1])) % 360.0, r2
    return preds[0], r2


def confounders(ev) -> list[str]:
    """What a confounded candidate is confounded with: position and the covariates of the model's terms."""
    inputs = [i for s in ev.sm.term_specs for i in s.inputs]
    return list(dict.fromkeys(["position", *[i for i in inputs if i != "position"]]))


def advice(
    covariate: str, proxies_of_time: list[str] | None = None, single_pass: bool = False
) -> str:
    """The survey that would separate a confounded candidate from position."""
    if single_pass:
        what = "time, a counter" + ("" if covariate == "t" else f", {covariate}")
        return (
            f"this survey is one pass: anything that drifts along it ({what}) is a function of the "
            "distance along the line, like the map itself; repeat the line later, in the other "
            "direction too, or cross it, so that the same place is seen at different times and values"
        )
    if covariate == "t" or covariate in (proxies_of_time or []):
        return (
            "repeat a leg (or the whole line) later, over the same ground: a change in time then shows as a "
            "difference at the same place, which no map can explain"
        )
    if covariate in HEADING_LIKE or covariate.startswith("heading_rel_"):
        return (
            "cross the lines, or run each leg in both directions: the same place is then seen at different "
            f"headings, which separates a {covariate}-dependent error from the map"
        )
    if covariate in SPEED_LIKE or covariate.startswith("wheel"):
        return (
            "run legs at two boat speeds over the same ground: the same place is then seen at different "
            f"speeds, which separates a {covariate}-dependent error from the map"
        )
    return (
        f"on this survey {covariate} follows the position at the scale the map resolves; to tell a "
        f"{covariate} effect from the map, cover places close together where {covariate} differs (closer "
        "lines, or lines across the first ones)"
    )
