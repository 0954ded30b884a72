"""The flow frame of a flow that oscillates (a tidal stream, a seiche): the principal axis of the velocity over
the cycle at each place, fixed in time.

A vector's usual frame follows the flow's direction, in time too (a GP in `t`). A reversing tide turns that
frame by 180 degrees at every slack water, and the along-flow component becomes the speed, |u cos wt|, which
no harmonic term can fit or predict. So when a target's terms hold a tide or a seiche, the frame models are
`const + gp(position, matern32)` plus those terms (uniform in space) for the east and north components, and
the frame at a place is the major axis of `E[v v']` over the cycle: `m m' + C`, with m the place's mean
velocity and C the covariance of the time terms' velocity over the cycle. Along that axis the flow is
`m + tide`, signed, a sum of harmonics; the ellipse's minor axis is across it. The axis points with the
mean flow where the mean is clear, else with the survey's overall axis (north-going if even that has no
mean), so that it never flips between neighbouring places.

Where the "mean flow" is mostly an instrument's error (a yacht's leeway, a speed log's calibration), the
axis at each place follows that error, and a uniform tide projected on it changes amplitude from place to
place; where a real stream turns with its channels, the axis at each place is the right one. Which of the
two (that axis, or the survey's overall axis at every place) a survey gets is chosen by the held-out
vector's error (host/workbench/targets/axis_choice.py).
"""

from __future__ import annotations

import math

import numpy as np
from forcemap.host.workbench.engine.hypersearch import term_inputs
from forcemap.host.workbench.survey.table import is_circular
from forcemap.host.workbench.terms import registry

CYCLE_SAMPLES = 512
# the mean flow orients the axis where its projection is at least this share of the cycle's rms along it
MEAN_CLEAR = 0.1


def uniform(term: str) -> str:
    """A time term's uniform form (the frame needs the axis, not the ellipse's variation over the reach)."""
    return registry.uniform(registry.parse_term(term, is_circular))


def along_reference(terms: tuple[str, ...]) -> bool:
    """Whether time terms put a vector along its reference stations' flood axes (a tide on a reference)."""
    return any(registry.caps(registry.parse_term(t, is_circular)).along_reference for t in terms)


def time_part(model, X: dict) -> np.ndarray:
    """The fitted model's time terms (tide, seiche) summed at inputs `X`, in the target's units."""
    n = len(next(iter(X.values())))
    out, i = np.zeros(n), 0
    for t, m in zip(model.feat_terms_, model.design_.sizes, strict=True):
        if t.on_flow_axis:
            out += t.features(term_inputs(t, X)) @ model.posterior_["mu"][i : i + m]
        i += m
    return out * model.y_scale_


def cycle_inputs(model, survey) -> dict:
    """Times over the survey or the model's longest period, whichever is longer (at the survey's centre)."""
    longest = 0.0
    for t in model.feat_terms_:
        longest = max(longest, *t.periods_s(), 0.0)
    span = max(float(np.ptp(survey.trel)), longest)
    trel = np.linspace(0.0, span, CYCLE_SAMPLES)
    return {
        "position": np.zeros((CYCLE_SAMPLES, 2)),
        "t": trel,
        "utc": survey.t0 + trel,
        "lat": np.full(CYCLE_SAMPLES, survey.lat0),
    }


def cycle_stats(me, mn, survey) -> tuple[np.ndarray, np.ndarray]:
    """The time terms' mean velocity (2,) and its covariance (2, 2) over the cycle."""
    X = cycle_inputs(me, survey)
    tau = np.vstack([time_part(me, X), time_part(mn, X)])
    return tau.mean(axis=1), np.cov(tau, bias=True)


def axes(mean_e, mean_n, tau_mean, tau_cov) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit major axes (east, north) of `m m' + C` at each place, and the largest eigenvalue."""
    ve, vn = mean_e + tau_mean[0], mean_n + tau_mean[1]
    a, b, c = ve * ve + tau_cov[0, 0], ve * vn + tau_cov[0, 1], vn * vn + tau_cov[1, 1]
    theta = 0.5 * np.arctan2(2 * b, a - c)
    lam = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return np.cos(theta), np.sin(theta), lam


def oriented(ue, un, lam, mean_e, mean_n, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The axes pointed with the mean flow where it is clear, else with `ref`."""
    proj = ue * mean_e + un * mean_n
    clear = np.abs(proj) > MEAN_CLEAR * np.sqrt(np.maximum(lam, 1e-300))
    sign = np.where(clear, np.sign(proj), np.sign(ue * ref[0] + un * ref[1]))
    sign = np.where(sign == 0, 1.0, sign)
    return sign * ue, sign * un


def reference(mean_e, mean_n, tau_mean, tau_cov) -> np.ndarray:
    """The survey's overall axis, with its mean flow, else north-going."""
    me, mn = float(np.mean(mean_e)), float(np.mean(mean_n))
    spread = np.cov(np.vstack([mean_e, mean_n]), bias=True) if len(mean_e) > 1 else np.zeros((2, 2))
    ue, un, lam = axes(np.array([me]), np.array([mn]), tau_mean, tau_cov + spread)
    ref = np.array([ue[0], un[0]])
    proj = ref[0] * me + ref[1] * mn
    if abs(proj) > MEAN_CLEAR * math.sqrt(max(float(lam[0]), 1e-300)):
        return ref * math.copysign(1.0, proj)
    return ref if (ref[1] > 0 or (ref[1] == 0 and ref[0] >= 0)) else -ref


def mean_flow(model, X: dict) -> np.ndarray:
    """The model's prediction without its time terms (the place's mean velocity component)."""
    return model.predict(X) - time_part(model, X)


def axis_frame(me, mn, survey, X: dict, mean: tuple | None = None, one_axis: bool = False):
    """Unit vectors (east, north) of the oscillating flow's axis at the places of `X` (fixed in time); the
    places' mean velocity may be given (`mean`: a cross-validated one). With `one_axis`, the survey's
    overall axis at every place (host/workbench/targets/axis_choice.py says when)."""
    tau_mean, tau_cov = cycle_stats(me, mn, survey)
    rows = survey_inputs_cached(survey)
    ref = reference(mean_flow(me, rows), mean_flow(mn, rows), tau_mean, tau_cov)
    if one_axis:
        n = len(next(iter(X.values())))
        return np.full(n, ref[0]), np.full(n, ref[1])
    if mean is None:
        mean = (mean_flow(me, X), mean_flow(mn, X))
    ue, un, lam = axes(mean[0], mean[1], tau_mean, tau_cov)
    return oriented(ue, un, lam, mean[0], mean[1], ref)


def survey_inputs_cached(survey) -> dict:
    """The survey's own places (at most 4,000 of them), for the overall axis."""
    n = survey.n
    idx = np.unique(np.linspace(0, n - 1, min(n, 4000)).astype(int))
    return {
        "position": survey.xy[idx],
        "t": survey.trel[idx],
        "utc": survey.columns["t"][idx],
        "lat": survey.columns["lat"][idx],
    }
