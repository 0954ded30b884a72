"""What a target's terms in time need from the survey, and what they say about a prediction at a time.

- a `seiche` without a period gets one estimated from the survey (`resolve_seiche`), and is recorded with it;
- a tide or a seiche on a wind or current sets the vector's flow frame to the oscillation's axis and
  moves both of its components (`frame_terms`, `all_terms`);
- a map asked for at a time far from the survey's says what each time term does there (`notes_at`): a
  tide predicts, a GP in `t` (or `water_level`) has reverted to its mean beyond a few lengthscales, a
  seiche's phase is carried on although a real seiche decays.
"""

from __future__ import annotations

import time

import numpy as np
from forcemap.host.workbench.targets.flow_axis import uniform
from forcemap.host.workbench.targets.survey_fits import survey_fits, survey_inputs
from forcemap.host.workbench.terms import registry
from forcemap.host.workbench.terms.base import TermSpec, span_words
from forcemap.host.workbench.terms.reference_maps import (
    describe_relation,
    reference_block,
    relation_maps,
)
from forcemap.host.workbench.terms.seiche import merian, resolve, seiche_block, with_period
from forcemap.host.workbench.terms.spec import BASELINE
from forcemap.host.workbench.terms.tide import constituents, describe_fit, ellipses, tide_block


def all_terms(specs: list[TermSpec]) -> tuple[str, ...]:
    """The terms among a target's term specs that oscillate along a flow axis (tide, seiche), as written."""
    return tuple(str(s) for s in specs if registry.caps(s).on_flow_axis)


def frame_terms(specs: list[TermSpec]) -> tuple[str, ...]:
    """The time terms the vector's frame models carry: their uniform form."""
    return tuple(dict.fromkeys(uniform(t) for t in all_terms(specs)))


def resolve_seiche(sm) -> None:
    """Replace each `seiche` without a period in the `SurveyModel`'s specs by `seiche(P s)`, P estimated from
    the survey (host/workbench/terms/seiche.py); the estimate is kept as `sm.seiche_estimate`."""
    for i, spec in enumerate(sm.term_specs):
        if not registry.caps(spec).estimates_period or spec.options.get("period_s") is not None:
            continue
        others = [s for s in sm.term_specs if s is not spec]
        fits = survey_fits(sm.survey)
        models = _base_models(sm, others)
        est = resolve(models, sm.survey.trel, spec.options["harmonics"], fits.hyper_rows)
        depth = sm.survey.columns.get("depth")
        mean_depth = float(np.nanmean(depth)) if depth is not None else None
        est.merian = merian(est.period_s, mean_depth, float(np.ptp(sm.survey.xy, axis=0).max()))
        sm.term_specs[i] = with_period(spec, round(est.period_s, 1))
        sm.seiche_estimate = est


def _base_models(sm, others: list[TermSpec]) -> list:
    """Fitted models without the seiche whose residual shows it: the target's own (a scalar), or the
    vector's east and north components over position and the other time terms."""
    fits = survey_fits(sm.survey)
    X = survey_inputs(sm.survey, {i for s in others for i in s.inputs})
    if sm.vector is None:
        y = sm.survey.column(sm.target)  # the rows that have the target (target_rows)
        return [sm.new_primary(others).fit(X, y)]
    terms = [*BASELINE, *frame_terms(others)]
    e, n = sm.survey.components(sm.vector)
    out = []
    for y in (e, n):  # both there on every row the model is fitted on (target_rows)
        out.append(fits.model(terms).fit(X, y))
    return out


def iso(unix_s: float) -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(unix_s))


def _distance_s(at: float, t0: float, t1: float) -> float:
    return max(t0 - at, at - t1, 0.0)


def notes_at(model, survey, at: float) -> list[str]:
    """What each time term of a fitted `Model` does at UNIX time `at`, said when `at` is outside the
    survey's span (a tide, a seiche) or beyond a GP in time's lengthscale from it."""
    t0, t1 = float(survey.columns["t"].min()), float(survey.columns["t"].max())
    away = _distance_s(at, t0, t1)
    if away <= 0:
        return []
    when = f"{iso(at)} is {span_words(away)} {'after' if at > t1 else 'before'} the survey"
    notes = (
        term.note_at(model.theta_[sl], away, when)
        for term, sl in zip(model.feat_terms_, model.h_slices_, strict=True)
    )
    return [n for n in notes if n]


def tide_summary(sm) -> dict:
    """A fitted `SurveyModel`'s tide and seiche: constituents of its modelled component (target units: the
    along-flow component of a speed, the across-flow one of a direction), a vector's tidal ellipses from its
    east and north frame models, the frame's axis and why (`axis_choice`), and a seiche's period (estimated,
    or as given)."""
    out: dict = {"constituents": constituents(sm.primary), "ellipses": [], "seiche": None}
    k = tide_block(sm.primary)
    if k is not None:
        out["selection"] = sm.primary.feat_terms_[k].selection.describe()
    if sm.secondary is not None and sm.frame_terms:
        me, mn = survey_fits(sm.survey).frame(sm.vector, sm.frame_terms)
        out["ellipses"] = ellipses(me, mn)
        out["axis"] = sm.axis.to_json()
    if reference_block(along_across(sm)[0]) is not None:
        out["reference"] = reference_summary(sm)
    k = seiche_block(sm.primary)
    if k is not None:
        est = sm.seiche_estimate
        term = sm.primary.feat_terms_[k]
        out["seiche"] = {"period_s": term.period_s, "estimated": est is not None}
        if est is not None:
            out["seiche"].update(
                period_sd_s=est.period_sd_s, power=est.power, fap=est.fap, text=est.describe()
            )
    return out


def reference_summary(sm) -> dict:
    """A tide on a reference in numbers: the file, the stations the survey's rows take, and the relation
    over the track (median and 5-95 % of the flood's and the ebb's ratio, offset and turn)."""
    from forcemap.host.workbench.survey import reference

    s = sm.survey
    xy = s.xy[:: max(1, s.n // 2000)]
    maps = relation_at(sm, xy)
    out: dict = {
        "file": s.reference.source,
        "chosen": s.reference.chosen,
        "stations": [st.describe() for st in reference.stations_used(s)],
    }
    for key, v in maps.items():
        if key != "station":
            out[key] = [float(np.percentile(v, q)) for q in (5, 50, 95)]
    return out


def along_across(sm) -> tuple:
    """The models that hold a tide on a reference: the relation fitted first (targets/reference_part.py)
    and nothing across; else a vector's along and across components (a scalar target's own, None)."""
    if getattr(sm, "relation", None) is not None:
        return sm.relation, None
    if sm.secondary is None:
        return sm.primary, None
    return (sm.primary, sm.secondary) if sm.primary_is_along else (sm.secondary, sm.primary)


def reference_lines(sm) -> list[str]:
    """A tide on a reference current in words: the reference and its stations, the relation to them."""
    if reference_block(along_across(sm)[0]) is None:
        return []
    from forcemap.host.workbench.survey.reference import describe as describe_reference

    s = sm.survey
    xy = s.xy[:: max(1, s.n // 2000)]
    lines = describe_relation(*along_across(sm), xy, relation_base(sm, xy))
    return [f"tide: {describe_reference(s)}", *lines]


def relation_at(sm, xy):  # type: ignore[no-untyped-def]
    """A fitted `SurveyModel`'s relation to its reference stations at places `xy` (terms/reference_maps.py),
    with each place's station; a refusal without a tide on a reference."""
    from forcemap.host.workbench.errors import WorkbenchError
    from forcemap.host.workbench.survey import reference

    maps = relation_maps(*along_across(sm), xy, relation_base(sm, xy))
    if maps is None:
        raise WorkbenchError(
            "this fit has no tide on a reference current: fit with effects=['tide'] on a survey read "
            "with reference_current= (--reference-current)"
        )
    ref = reference.need(sm.survey)
    lat, lon = reference.latlon(sm.survey, xy)
    maps["station"] = np.array([ref.ids[i] for i in ref.station_index(lat, lon)])
    return maps


def relation_base(sm, xy):  # type: ignore[no-untyped-def]
    """What the along weights of a tide on a reference depart from at places `xy`: the station's
    prediction on the model's component where the model fits the departure (targets/reference_part.py)."""
    if getattr(sm, "station_rows", None) is None:
        return 0.0
    from forcemap.host.workbench.survey import reference

    aspect = sm.vector.aspect
    if aspect in ("speed", "dir"):
        return 1.0
    ue, un = reference.flood_axes(sm.survey, xy)
    return ue if aspect == "east" else un


def describe(sm) -> list[str]:
    """The fit's time terms in words, for `fit`'s summary."""
    lines = describe_fit(sm.primary) + reference_lines(sm)
    summary = tide_summary(sm) if lines or sm.seiche_estimate else {"ellipses": []}
    for e in summary["ellipses"]:
        lines.append(
            f"  {e['name']} ellipse (east/north): major {e['major']:.3g} +- {e['major_sd']:.2g} m/s "
            f"toward {e['direction_deg']:.1f} +- {e['direction_sd_deg']:.1f} deg at the phase (then back), minor "
            f"{e['minor']:+.3g} +- {e['minor_sd']:.2g} m/s, phase {e['phase_deg']:.1f} +- "
            f"{e['phase_sd_deg']:.1f} deg"
        )
    if sm.seiche_estimate is not None:
        lines.append(sm.seiche_estimate.describe())
    if sm.secondary is not None and sm.axis is not None:
        lines.append(f"  {sm.axis.line()}")
    return lines
