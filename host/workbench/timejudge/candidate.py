"""The time candidate judged where the boat comes back: which values are compared at the revisits, which
pairs, and which term the verdict advises.

What is compared is what the current model leaves (every term found so far, the map, no time): a scalar's
residual, a vector's east and north residuals. The map takes out what the field does across the revisit
radius; fitted without time, it cannot make the differences depend on time where there is no change in time,
so the permutation null stays exact. Where there is one, the map takes part of it into the places the boat
was at each time: the radius is kept to half the map's length scale, where the map cannot take much.
"""

from __future__ import annotations

import hashlib
import weakref
from typing import NamedTuple

import numpy as np
from forcemap.host.workbench.survey.table import family, unit_of
from forcemap.host.workbench.terms import registry
from forcemap.host.workbench.timejudge.judge import M2_S, TimeVerdict, judge_time
from forcemap.host.workbench.timejudge.revisits import (
    MIN_RADIUS_M,
    RevisitPairs,
    revisit_pairs,
    stretch_length,
    target_radius,
)

# fewer revisits than these cannot judge time (a permutation of fewer stretches cannot be significant)
MIN_PAIRS = 50
MIN_CROSSINGS = 5
# a record shorter than this share of M2's period sees a tide as a steady rise or fall: the two are one
# function of time there, and the advice is the term that assumes less
TIDE_SPAN_SHARE = 0.25
# a boat that moves less than this in a stretch holds its place (a mooring's swing, a GNSS's wander)
STATION_M = 10.0
# what a change that follows the reference station advises: its ratio and offset mapped (`fit --effects
# tide` with a reference fits the same)
REFERENCE_TERM = "tide(reference, position)"
# each live model's judged values (`judged_values_once`), with a digest of the residuals they were judged on
_JUDGED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def judged_values(sm) -> np.ndarray:
    """What the model leaves at each row, one column per component: a scalar's residual, a vector's east
    and north residuals from models of each component with the same terms (a tidal stream or a seiche
    moves the water back and forth, which its speed alone may hide)."""
    if sm.vector is None:
        return (sm.y_primary - sm.primary.predict(sm.X))[:, None]
    from forcemap.host.workbench.targets.target_model import SurveyModel

    own = set(sm.own_columns())
    terms = [str(t) for t in sm.term_specs if not own & set(t.inputs)]
    cols = []
    for aspect in ("east", "north"):
        m = SurveyModel(sm.survey, sm.vector.column(aspect), terms, max_basis=sm.max_basis).fit()
        cols.append(m.y_primary - m.primary.predict(m.X))
    return np.column_stack(cols)


def judged_values_once(sm, resid: np.ndarray) -> np.ndarray:
    """`judged_values(sm)`, computed once while the model lives and leaves the residuals `resid`: diagnose
    judges a model's revisits, then again with its threshold when the p-value lies near it, and a vector's
    values are two models fitted anew."""
    digest = hashlib.sha1(np.ascontiguousarray(resid, float).tobytes()).hexdigest()
    kept = _JUDGED.get(sm)
    if kept is None or kept[0] != digest:
        kept = _JUDGED[sm] = (digest, judged_values(sm))
    return kept[1]


def under_way(xy: np.ndarray, t: np.ndarray, radius: float, stretch_s: float) -> np.ndarray:
    """Rows where the boat moves more than the revisit radius (at most STATION_M) within a stretch: a boat
    that stays in one place (at the dock, at anchor, swinging on its mooring) makes no passes that come
    back, and its hours there would outnumber every crossing of the survey."""
    radius = min(radius, STATION_M)
    half = 0.5 * stretch_s
    before = np.column_stack([np.interp(t - half, t, xy[:, k]) for k in (0, 1)])
    after = np.column_stack([np.interp(t + half, t, xy[:, k]) for k in (0, 1)])
    return np.hypot(*(after - before).T) > radius


class Revisits(NamedTuple):
    """What the time judge compares: the rows judged (under way, their values finite), their revisit pairs
    (`rp.pairs` index `rows`), how many rows were left out as held in one place, and every row's judged
    values (`judged_values`)."""

    rows: np.ndarray
    rp: RevisitPairs
    held: int
    values: np.ndarray


def revisits_of(sm, radius_m: float | None = None) -> Revisits | None:
    """The revisits of the fitted model `sm`; None when the track comes back too little to judge time."""
    found = every_revisit(sm, radius_m)
    return found if found is not None and enough(found.rp) else None


def enough(rp: RevisitPairs) -> bool:
    """Whether revisits are enough to judge time: MIN_PAIRS pairs on MIN_CROSSINGS crossings."""
    return len(rp.pairs) >= MIN_PAIRS and rp.crossings >= MIN_CROSSINGS


def every_revisit(sm, radius_m: float | None = None, judged: bool = True) -> Revisits | None:
    """Every revisit of the fitted model `sm`, however few; None when fewer than 2 MIN_PAIRS rows are
    under way with finite values. Without `judged`, the values are the model's own residual (enough to
    count the revisits, without fitting a vector's components)."""
    s = sm.survey
    t = s.trel
    resid = sm.y_primary - sm.primary.predict(sm.X)
    stretch = stretch_length(t, resid)
    radius_m = max(target_radius(sm) if radius_m is None else radius_m, MIN_RADIUS_M)
    moving = under_way(s.xy, t, radius_m, stretch)
    values = judged_values_once(sm, resid) if judged else resid[:, None]
    keep = moving & np.isfinite(values).all(axis=1)
    if keep.sum() < 2 * MIN_PAIRS:
        return None
    rows = np.flatnonzero(keep)
    rp = revisit_pairs(s.xy[rows], t[rows], radius_m, stretch)
    return Revisits(rows, rp, int((~moving).sum()), values)


def too_few_note(sm) -> str:
    """Why the revisits could not judge time on the fitted model `sm`: how often the track comes back, and
    how often it needs to."""
    found = every_revisit(sm, judged=False)
    need = f"{MIN_CROSSINGS} crossings and {MIN_PAIRS} pairs are needed"
    if found is None:
        seen = f"fewer than {2 * MIN_PAIRS} rows under way with a value"
    else:
        rp = found.rp
        seen = f"{rp.crossings} crossings and {len(rp.pairs)} pairs within {rp.radius_m:.0f} m"
    level = (
        "; nor can the crossings give a water level: a gauge can (--water-level)"
        if family(sm.target) == "depth"
        else ""
    )
    return (
        f"the track comes back too little to judge time where it returns ({seen}; {need}): judged on "
        "blocks, where along a track that does not come back a change in time cannot be told from a "
        f"change along the track{level}"
    )


def time_verdict(
    sm, radius_m: float | None = None, threshold: float | None = None
) -> tuple[TimeVerdict, int] | None:
    """The revisits' verdict on time for the fitted model `sm`, and how many rows were left out as held in
    one place; None when the track comes back too little to judge it. With a `threshold`, the p-value is
    resolved on either side of it (`judge_time`)."""
    found = revisits_of(sm, radius_m)
    if found is None:
        return None
    verdict = judge_time(
        *judged_pairs(sm, found), threshold=threshold, reference=reference_form(sm, found)
    )
    # a vector is judged on its east and north components
    verdict.unit = "m/s" if sm.vector is not None else unit_of(sm.target)
    return verdict, found.held


def judged_pairs(sm, found: Revisits) -> tuple:
    """What `judge_time` is given for the revisits `found` of the model `sm`: the pairs' differences (the
    later sample's values minus the earlier's), the pairs, and the judged rows' positions and headings."""
    rows, rp, _, values = found
    v = rows[rp.pairs]
    heading = sm.survey.columns.get("heading")
    hd = None if heading is None else heading[rows]
    return values[v[:, 1]] - values[v[:, 0]], rp, sm.survey.xy[rows], hd


def reference_form(sm, found: Revisits):
    """The survey's reference current as a form for the revisits `found` of a current's model `sm`; None
    without a reference, for another target (a station predicts the current, not the wind or a depth), or
    where the model maps the place's relation to it already (a single relation over the reach leaves its
    map to find)."""
    from forcemap.host.workbench.timejudge.reference_form import ReferenceForm

    s = sm.survey
    if getattr(s, "reference", None) is None or family(sm.target) != "current":
        return None
    if REFERENCE_TERM in {str(t) for t in sm.term_specs}:
        return None
    rows = found.rows
    utc0 = float(s.t0 + found.rp.start_s)
    return ReferenceForm(
        s.reference, s.columns["lat"][rows], s.columns["lon"][rows], utc0, found.rp
    )


def time_term(verdict: TimeVerdict, target: str) -> str:
    """The term a verdict advises for `target`: a tide, a periodic term (a seiche, at the fit's own period
    where it agrees: `fitted_seiche`), or a smooth change (a drift, a stage: `water_level` under depth, a
    GP in t otherwise; a wind's gusts and veers too)."""
    fam = family(target)
    smooth = smooth_time_term(target)
    if fam == "wind":
        return smooth
    kind = verdict.best.name
    if kind == "reference":
        return REFERENCE_TERM
    if kind == "tide" and short_for_a_tide(verdict):
        kind = "drift"
    if kind == "periodic":
        term = f"seiche({verdict.fitted_period_s or verdict.best.period_s:.0f} s)"
    else:
        term = "tide" if kind == "tide" else smooth
    return term if is_time_term(term) else smooth


def fitted_seiche(sm, verdict: TimeVerdict):
    """`fit`'s own estimate of a periodic change's period on the model `sm` (the term `seiche` resolved as
    `fit` resolves it: the residual's periodogram and the marginal likelihood, on every row, the map beside
    it), when it agrees with the revisits' period within twice their combined sd; None when it does not or
    cannot be made. The revisits see time where the boat comes back; the fit sees every row, so where the two
    agree the fit's period is the more precise."""
    from forcemap.host.workbench.errors import WorkbenchError
    from forcemap.host.workbench.targets.target_model import SurveyModel
    from forcemap.host.workbench.terms import time_terms

    if verdict.best.name != "periodic" or verdict.period_sd_s is None:
        return None
    terms = [str(t) for t in sm.term_specs if not registry.caps(t).predicts_in_time]
    probe = SurveyModel(sm.survey, sm.target, [*terms, "seiche"], max_basis=sm.max_basis)
    try:
        time_terms.resolve_seiche(probe)
    except (WorkbenchError, np.linalg.LinAlgError, ValueError):
        return None
    est = probe.seiche_estimate
    if est is None or not np.isfinite(est.period_sd_s):
        return None
    combined = np.hypot(est.period_sd_s, verdict.period_sd_s)
    return est if abs(est.period_s - verdict.best.period_s) <= 2.0 * combined else None


def smooth_time_term(target: str) -> str:
    """The term of a smooth change in time: the water level under depth, a GP in t otherwise."""
    return "water_level" if family(target) == "depth" else "gp(t, matern32)"


def is_time_term(term: str) -> bool:
    """Whether `term` parses as a term in time (not as a covariate of that name)."""
    from forcemap.host.workbench.survey.table import is_circular

    return registry.in_time(registry.parse_term(term, is_circular))


def short_for_a_tide(verdict: TimeVerdict) -> bool:
    """Whether the survey is too short to tell a tide from a steady rise or fall."""
    return verdict.span_s < TIDE_SPAN_SHARE * M2_S
