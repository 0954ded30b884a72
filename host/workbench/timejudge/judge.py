"""Time judged where the boat comes back: do two passes over one place differ by more than their noise, in a
way that follows the time between them?

The current model (every term found so far, no time) leaves residuals; at each revisit pair
(host/workbench/timejudge/revisits.py) their difference is what the map and the terms cannot explain. Under "no time
effect" those differences do not depend on when the passes were made. Each form a change in time can take is
fitted to them by least squares, as the difference of a function of time at the pair's two times:

- a drift (stage, a slow rise or fall): linear and quadratic in t;
- a periodic change at each of a ladder of periods from four stretches to twice the survey (a seiche), and
  at the tidal periods M2 and K1 (a tide).

The share of the differences' sum of squares a form explains is its statistic. Its null comes from the data
itself: whole stretches of track (as long as the residuals stay correlated) exchange their times at random,
which keeps every pair's difference and every dependence inside a stretch, and breaks only the link with time.
The forms are judged together (each share standardised by its own null, the largest against the largest of
every permutation), so trying many periods costs no false findings. A smooth signal's time-shifted copies are no
null: they are the same signal.

Two things a pair's difference may owe to other than time are projected out first: the displacement between
its two samples (the field's gradient across the revisit radius), and two harmonics of the heading (an
instrument that reads differently with the bow's direction, a misaligned sensor or a heeling hull: legs sailed
at set times would otherwise look like a change in time).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field, replace

import numpy as np
from forcemap.host.workbench.timejudge.forms import (
    M2_S,
    FittedChange,
    FormLadder,
    PermutedTimes,
    Projector,
    clipped,
    nuisance,
    pair_shares,
    periodic_columns,
)
from forcemap.host.workbench.timejudge.reference_form import ReferenceForm, ratio_and_offset
from forcemap.host.workbench.timejudge.revisits import RevisitPairs
from forcemap.host.workbench.validation.cv import gain_sd

__all__ = ["M2_S", "Form", "TimeVerdict", "judge_time"]

PERMUTATIONS = 999
# and at most this many, drawn BATCH at a time while the p-value is too close to a threshold to decide
# (`undecided`): a Bonferroni threshold of 0.05 / 24 = 0.0021 is two exceedances in 999
MAX_PERMUTATIONS = 9999
BATCH = 1000
# after PERMUTATIONS, a p-value within this factor of the threshold (either way) is undecided; the factor's
# logarithm narrows as the square root of the permutations drawn, as the p-value's sampling error does
RESOLVE = 10.0
# resamples of the stretches for the period's sd
BOOTSTRAP = 200
# the periods a tide has (s): semidiurnal 12.0-12.66 h, diurnal 23.93-25.82 h
TIDAL_BANDS = ((12.0 * 3600, 12.66 * 3600), (23.93 * 3600, 25.82 * 3600))
# forms closer than this in log-likelihood cannot be told apart (a likelihood ratio of e^2)
TELL_APART = 2.0
# the first draws of the last few judgements (`first_draws`), by a digest of what they were drawn for
DRAWN_KEPT = 4
_DRAWN: dict[str, tuple[np.ndarray, dict]] = {}


@dataclass
class Form:
    """One shape a change in time can take, fitted to the revisit differences."""

    name: str  # "drift", "tide", "periodic", "reference"
    period_s: float | None
    share: float  # share of the differences' sum of squares it explains
    p_value: float


@dataclass
class TimeVerdict:
    """What the revisits say about time: how many judged it, what they showed, how sure, and its form."""

    pairs: int
    crossings: int
    span_s: float  # the judged rows' duration
    stretch_s: float
    radius_m: float
    rms_difference: float  # RMS of the pairs' differences, in the target's unit
    share: float  # cross-validated share of their mean square the best form explains
    p_value: float
    permutations: int
    best: Form
    forms: list[Form] = field(default_factory=list)
    period_sd_s: float | None = None
    indistinct: list[str] = field(default_factory=list)  # forms the data cannot tell from the best
    # `fit`'s own estimate of a periodic best's period, where it agrees (time_candidate.fitted_seiche)
    fitted_period_s: float | None = None
    fitted_period_sd_s: float | None = None
    # how many crossings the fitted change rests on, and the times (s) of the two passes of the one that
    # carries most of it (`evidence`)
    evidence_crossings: float = 0.0
    evidence_at_s: tuple[float, float] = (0.0, 0.0)
    # the fitted change's size in the target's unit (`time_forms.FittedChange`): a drift's from the first
    # pass the revisits compare to the last (the times, s, in `change_span_s`), a period's amplitude
    change: float = 0.0
    change_sd: float = 0.0  # over the stretches resampled
    # a part of a cycle that turns between the first and last compared passes (`FittedChange.turns`): its
    # largest departure from its value at the first, and its sd; else 0
    departure: float = 0.0
    departure_sd: float = 0.0
    change_span_s: tuple[float, float] = (0.0, 0.0)
    # the first judged row's time (every time here is in s since the survey's start)
    start_s: float = 0.0
    unit: str = ""  # of the differences and the change (time_candidate.time_verdict sets it)
    improvement_sd: float = 0.0  # the sd of `improvement`, a crossing the paired unit (`cv_share`)
    # a best form that follows the reference station (`reference_form`): the station, and the place's ratio
    # to it and its offset (s, the place later) from the form's coefficients
    station: str = ""
    ratio: float = 0.0
    offset_s: float = 0.0

    @property
    def improvement(self) -> float:
        """The relative drop of the differences' RMS once the fitted change in time is taken out."""
        return 1.0 - math.sqrt(max(1.0 - self.share, 0.0))

    @property
    def rms_time(self) -> float:
        return self.rms_difference * math.sqrt(max(self.share, 0.0))


def form_at(ladder: FormLadder, i: int, share: float, p: float) -> Form:
    """The ladder's form i, named by its kind (`kind_of`): the drift, or a periodic change."""
    share, p = float(share), float(p)
    form = Form("drift", None if i == 0 else float(ladder.periods[i - 1]), share, p)
    return Form(kind_of(form, ladder.span, None), form.period_s, share, p)


def kind_of(form: Form, span_s: float, sd_s: float | None) -> str:
    """What a fitted form is: a tide (a period in a tidal band), a periodic change (a period the record
    holds at least once, two sd above it included), or a drift (no period, or a period that may be longer
    than the record: a part of a cycle is a smooth rise or fall, whatever the rest of the cycle would be)."""
    if form.period_s is None:
        return "drift"
    if is_tidal(form.period_s, sd_s or 0.0):
        return "tide"
    return "periodic" if form.period_s + 2.0 * (sd_s or 0.0) <= span_s else "drift"


def determined(best: Form, sd_s: float | None) -> bool:
    """Whether the best form's shape is one the record can name: no period (a drift), a tidal period, or a
    period whose profile likelihood falls on both sides of its peak (`refined_period` gives it an sd). A
    period the profile leaves open (on the Gulf of Finland's 0.6-m rise, 14,156 s in a 14,843-s record, the
    drift of 15,062 s as likely) is one rise or fall, whatever the rest of a cycle would be: a drift."""
    return best.period_s is None or sd_s is not None or is_tidal(best.period_s)


def is_tidal(period_s: float, sd_s: float = 0.0) -> bool:
    """Whether a period (within two sd) lies in a tidal band."""
    return any(lo - 2 * sd_s <= period_s <= hi + 2 * sd_s for lo, hi in TIDAL_BANDS)


def permutation_p(obs: np.ndarray, null: np.ndarray) -> tuple[np.ndarray, float]:
    """Each form's permutation p-value, and the p-value of the forms judged together: each form's share
    standardised by its own null's mean and sd, the largest of them against the same largest in every
    permutation (a max-statistic, as Westfall and Young's, without the ties of discrete p-values)."""
    n = len(null)
    per_form = (1 + (null >= obs).sum(axis=0)) / (1 + n)
    mu, sd = null.mean(axis=0), null.std(axis=0) + 1e-12
    z_obs = float(((obs - mu) / sd).max())
    z_null = ((null - mu) / sd).max(axis=1)
    return per_form, float((1 + (z_null >= z_obs).sum()) / (1 + n))


def judge_time(
    d: np.ndarray,
    rp: RevisitPairs,
    xy: np.ndarray,
    heading: np.ndarray | None = None,
    permutations: int = PERMUTATIONS,
    seed: int = 0,
    threshold: float | None = None,
    reference: ReferenceForm | None = None,
) -> TimeVerdict:
    """Judge a change in time from the residual differences `d` (one row per pair of `rp`, one column per
    vector component, the later sample minus the earlier). With a `threshold`, permutations are added up to
    MAX_PERMUTATIONS while the p-value cannot yet say on which side of it the exact one lies. With a
    `reference`, its station's prediction is one more form, judged with the others."""
    d = np.asarray(d, float).reshape(len(rp.pairs), -1)
    rms = float(np.sqrt(np.mean((d * d).sum(axis=1))))
    proj = Projector(nuisance(rp, xy, heading))
    d = proj(clipped(d))
    span = float(np.ptp(rp.t))
    ladder = FormLadder(span, rp.stretch_s)
    ta, tb = rp.times()
    forms, best_i, p, drawn = judged_forms(
        d, rp, ladder, proj, reference, permutations, seed, threshold
    )
    n_eff = max(rp.crossings, 2)
    best, sd, columns = best_columns(d, rp, forms[best_i], best_i, ladder, proj, reference, seed)
    n_evidence, at = evidence(d, rp, columns)
    covered = (float(min(ta.min(), tb.min())), float(max(ta.max(), tb.max())))
    basis = reference.basis if best.name == "reference" else None
    fitted = FittedChange(best.name, best.period_s, span, covered, basis)
    change = fitted(d, columns)
    change_sd = fitted.sd(d, columns, rp, seed) if change else 0.0
    turns = (
        best.name == "drift" and best.period_s is not None and fitted.turns(d, columns, rp, seed)
    )
    share, share_sd = cv_share(d, rp, columns)
    station, ratio, offset = followed_station(best, reference, columns, d)
    return TimeVerdict(
        pairs=len(rp.pairs),
        crossings=rp.crossings,
        span_s=span,
        stretch_s=rp.stretch_s,
        radius_m=rp.radius_m,
        rms_difference=rms,
        share=share,
        improvement_sd=share_sd,
        p_value=p,
        permutations=drawn,
        best=best,
        forms=forms,
        period_sd_s=sd,
        indistinct=indistinct(forms, best, n_eff),
        evidence_crossings=n_evidence,
        evidence_at_s=(at[0] + rp.start_s, at[1] + rp.start_s),
        change=change,
        change_sd=change_sd,
        departure=fitted.departure(d, columns) if turns else 0.0,
        departure_sd=fitted.sd(d, columns, rp, seed, of=fitted.departure_of) if turns else 0.0,
        change_span_s=(covered[0] + rp.start_s, covered[1] + rp.start_s),
        start_s=rp.start_s,
        station=station,
        ratio=ratio,
        offset_s=offset,
    )


def best_columns(d, rp: RevisitPairs, best: Form, i: int, ladder, proj, reference, seed: int):
    """The best form named by its kind, its period refined with its sd (None for a form without one, or a
    period the record leaves open: then a drift), and its columns at the revisit pairs."""
    ta, tb = rp.times()
    sd = None
    if best.name == "reference":
        return best, None, np.column_stack(reference.columns(ta, tb, proj))
    if best.period_s is None:
        columns = ladder.columns(i, ta, tb, proj)
    else:
        period, sd = refined_period(d, ta, tb, best.period_s, max(rp.crossings, 2), proj)
        if sd is not None:
            sd = max(sd, bootstrap_period_sd(d, ta, tb, period, rp, proj, seed))
        best = replace(best, period_s=period)
        columns = np.column_stack(periodic_columns(ta, tb, np.array([2 * np.pi / period]), proj))
    span = float(np.ptp(rp.t))
    best = replace(best, name=kind_of(best, span, sd) if determined(best, sd) else "drift")
    return best, sd, columns


def followed_station(
    best: Form, reference, columns: np.ndarray, d: np.ndarray
) -> tuple[str, float, float]:
    """A reference best form's station, and the place's ratio to it and offset (s) that its coefficients
    give; ("", 0, 0) for another best."""
    if best.name != "reference":
        return "", 0.0, 0.0
    ratio, offset = ratio_and_offset(np.linalg.lstsq(columns, d, rcond=None)[0])
    return reference.station.id, ratio, offset


def judged_forms(d, rp, ladder, proj, reference, permutations: int, seed: int, threshold):
    """Every form (the ladder's, then a `reference`'s) with its share at the observed times and its p-value
    against `permutations` draws of whole stretches' times exchanged (more while a `threshold` is
    `undecided`); the best form's index, the forms' p-value together, and the draws made. A reference
    form whose own p-value is as small as the forms' together is the best."""
    ta, tb = rp.times()
    obs = ladder.shares(d, ta, tb, proj)
    pt = PermutedTimes(rp, ladder, proj)

    def draws(orders: np.ndarray) -> np.ndarray:
        if reference is None:
            return pt.null(d, orders)
        return np.column_stack([pt.null(d, orders), reference.null(d, orders, proj)])

    if reference is not None:
        obs = np.append(obs, reference.share(d, ta, tb, proj))
    null, rng = first_draws(draws, d, rp, proj, permutations, seed, keep=reference is None)
    per_form, p = permutation_p(obs, null)
    while threshold is not None and undecided(p, len(null), threshold):
        more = min(BATCH, MAX_PERMUTATIONS - len(null))
        orders = np.array([rng.permutation(rp.n_stretches) for _ in range(more)])
        null = np.concatenate([null, draws(orders)])
        per_form, p = permutation_p(obs, null)
    best_i = best_form(obs, null)
    if reference is not None and per_form[-1] <= p:
        # a prediction given beforehand that alone carries the evidence for time is the cause to name: it
        # predicts beyond the survey, and what the ladder's best fits beyond it is left for the next round
        best_i = len(obs) - 1
    forms = [form_at(ladder, i, obs[i], per_form[i]) for i in range(len(ladder.omega) + 1)]
    if reference is not None:
        forms.append(Form("reference", None, float(obs[-1]), float(per_form[-1])))
    return forms, best_i, p, len(null)


def first_draws(
    draws, d: np.ndarray, rp: RevisitPairs, proj: Projector, permutations: int, seed: int, keep: bool
) -> tuple[np.ndarray, np.random.Generator]:
    """`draws(orders)` of the first `permutations` exchanges of the stretches, and the generator that drew
    them (to draw more from). With `keep`, drawn once for the same differences, pairs, projector and seed:
    diagnose judges a model's revisits, then again with its threshold when the p-value lies near it
    (`undecided`), and the second judgement begins with the same draws (the last few kept in `_DRAWN`, with
    the generator's state after them). A reference's form is made anew for each judgement: not kept."""
    what = (permutations, seed, d.shape, rp.n_stretches, rp.stretch_s)
    key = hashlib.sha1(repr(what).encode())
    for a in (d, rp.pairs, rp.stretch, rp.t, proj.Q):
        if a is not None:
            key.update(np.ascontiguousarray(a, float).tobytes())
    rng = np.random.default_rng(seed)
    hit = _DRAWN.get(key.hexdigest()) if keep else None
    if hit is not None:
        null, rng.bit_generator.state = hit[0], hit[1]
        return null.copy(), rng
    orders = np.array([rng.permutation(rp.n_stretches) for _ in range(permutations)])
    null = draws(orders)
    if keep:
        _DRAWN[key.hexdigest()] = (null.copy(), rng.bit_generator.state)
        while len(_DRAWN) > DRAWN_KEPT:
            _DRAWN.pop(next(iter(_DRAWN)))
    return null, rng


def evidence(d: np.ndarray, rp: RevisitPairs, A: np.ndarray) -> tuple[float, tuple[float, float]]:
    """How many crossings the change fitted by the columns `A` rests on: the participation ratio
    (sum s)^2 / sum s^2 of each crossing's share s of the sum of squares the change explains (every crossing
    alike: their number; one crossing: 1), and the mean times of the two passes of the crossing with the
    largest share. A change seen where one place was passed at the start and at the end rests on that one
    comparison, however many pairs it has."""
    w, *_ = np.linalg.lstsq(A, d, rcond=None)
    explained = ((A @ w) ** 2).sum(axis=1)
    crossing = rp.crossing_index()
    s = np.bincount(crossing, weights=explained)
    if not np.isfinite(s).all() or s.sum() <= 0:
        return 0.0, (0.0, 0.0)
    top = crossing == int(np.argmax(s))
    ta, tb = rp.times()
    return float(s.sum() ** 2 / (s * s).sum()), (float(ta[top].mean()), float(tb[top].mean()))


def undecided(p: float, n: int, threshold: float) -> bool:
    """Whether a p-value from `n` permutations lies too close to `threshold` to say on which side the exact
    one is: within RESOLVE ** sqrt(PERMUTATIONS / n) of it, either way (a factor of 10 at 999, 2.1 at
    9,999), and fewer than MAX_PERMUTATIONS drawn. The forms' standardisation is estimated from the same
    permutations, so the p-value varies between draws more than a count of exceedances would: on the
    fjord's level (bench/RESULTS.md), 0.002 to 0.018 over six seeds at 999, 0.0014 to 0.0044 at 9,999."""
    factor = RESOLVE ** math.sqrt(PERMUTATIONS / max(n, 1))
    return n < MAX_PERMUTATIONS and threshold / factor < p < threshold * factor


def best_form(obs: np.ndarray, null: np.ndarray) -> int:
    """The form that stands furthest above its own null (in its null's sd)."""
    z = (obs - null.mean(axis=0)) / (null.std(axis=0) + 1e-12)
    return int(np.argmax(z))


def log_lik(share: float, n_eff: int) -> float:
    """The Gaussian profile log-likelihood of a form (up to a constant), with n_eff independent units."""
    return -0.5 * n_eff * math.log(max(1.0 - share, 1e-12))


def refined_period(
    d, ta, tb, period_s: float, n_eff: int, proj: Projector
) -> tuple[float, float | None]:
    """The period at the top of the profile likelihood next to the ladder's `period_s` (a fine grid from
    half to twice it, climbed from the ladder's period to its local peak: the ladder's steps are 16 % apart,
    several sd of a well-determined period), and its sd: the half-width where the profile falls by 1/2 from
    the peak (None when it does not fall on both sides: the period is not determined by the survey)."""
    grid = period_s * np.geomspace(0.5, 2.0, 241)
    shares = pair_shares(d, *periodic_columns(ta, tb, 2 * np.pi / grid, proj))
    ll = np.array([log_lik(s, n_eff) for s in shares])
    top = len(grid) // 2
    while top < len(grid) - 1 and ll[top + 1] > ll[top]:
        top += 1
    while top > 0 and ll[top - 1] > ll[top]:
        top -= 1
    inside = ll >= ll[top] - 0.5
    lo, hi = top, top
    while lo > 0 and inside[lo - 1]:
        lo -= 1
    while hi < len(grid) - 1 and inside[hi + 1]:
        hi += 1
    if lo == 0 or hi == len(grid) - 1:
        return float(grid[top]), None
    return float(grid[top]), float(0.5 * (grid[hi] - grid[lo]))


def bootstrap_period_sd(
    d, ta, tb, period_s: float, rp: RevisitPairs, proj: Projector, seed: int = 0
) -> float:
    """The period's sd over the stretches resampled with replacement (BOOTSTRAP times), a pair weighted by
    the product of its two stretches' counts (Owen's pigeonhole bootstrap: a pair depends on both): where
    the peak moves when other passes happen to come back. The profile's curvature counts every crossing as
    independent evidence of one sinusoid, and a crossing's bootstrap does too; on the simulated laps of
    tests/test_time_judge.py they gave sds five and three times too small (16 seeds, periods of 50 and 74
    min), this one about 1.2 times too large (bench/bench_period_sd.py)."""
    grid = period_s * np.geomspace(2.0 / 3.0, 1.5, 81)
    C, S = periodic_columns(ta, tb, 2 * np.pi / grid, proj)
    sa, sb = rp.stretch[rp.pairs[:, 0]], rp.stretch[rp.pairs[:, 1]]
    n = rp.n_stretches
    rng = np.random.default_rng(seed)
    peaks = np.empty(BOOTSTRAP)
    for i in range(BOOTSTRAP):
        counts = np.bincount(rng.integers(0, n, n), minlength=n)
        w = np.sqrt(counts[sa] * counts[sb])[:, None]
        peaks[i] = grid[int(np.argmax(pair_shares(d * w, C * w, S * w)))]
    return float(np.std(peaks))


def indistinct(forms: list[Form], best: Form, n_eff: int) -> list[str]:
    """The kinds of form (drift, tide, periodic) other than the best's whose best member the data cannot
    tell from it."""
    top = log_lik(best.share, n_eff)
    out = []
    for kind in ("drift", "tide", "periodic", "reference"):
        members = [f for f in forms if f.name == kind]
        if kind == best.name or not members:
            continue
        if top - max(log_lik(f.share, n_eff) for f in members) < TELL_APART:
            out.append(kind)
    return out


def cv_share(d: np.ndarray, rp: RevisitPairs, A: np.ndarray, k: int = 5) -> tuple[float, float]:
    """A form's share of the differences, cross-validated: its coefficients fitted on the pairs away from
    a fold of stretches, judged on the pairs that touch it (pooled over the folds); and the sd of the
    relative drop of their RMS it gives (`TimeVerdict.improvement`), a crossing the paired unit."""
    fold = rp.stretch % k
    fa, fb = fold[rp.pairs[:, 0]], fold[rp.pairs[:, 1]]
    resid = np.zeros_like(d)
    for f in range(k):
        test = (fa == f) | (fb == f)
        if not test.any() or test.all():
            resid[test] = d[test]
            continue
        w, *_ = np.linalg.lstsq(A[~test], d[~test], rcond=None)
        resid[test] = d[test] - A[test] @ w
    base_sq, cand_sq = (d * d).sum(axis=1), (resid * resid).sum(axis=1)
    share = float(1.0 - cand_sq.sum() / base_sq.sum())
    return share, gain_sd(base_sq, cand_sq, rp.crossing_index())
