"""Find the missing effects: add a term in each candidate covariate, measure the blocked-CV gain, judge it against
a null and against what position can tell, add the finding and look again.

Causes and consequences. The boat's kinematics (sog, cog, crab = heading - cog, throttle) respond to the
current and wind that push it: at a held-out place they carry information about the very field being
mapped, so in spatially blocked CV they "predict" it although no effect is missing. A genuine instrument error
that grows with boat speed, or appears in turns, is different: it is there even where the field is known. So a
kinematic covariate of a wind or current target is credited only with the gain that survives random
(interleaved) folds, where every held-out sample has measured neighbours and the field is known: the smaller of
its blocked and random-fold gains, and the larger of the two p-values. Causes (depth, time, heading, ...) are
credited with their blocked-CV gain.

The finding rule (docs/WORKBENCH.md, "What a survey can and cannot tell"): a candidate is a missing
effect when its gain is at least FLOOR, its paired p-value passes Bonferroni, it gains more than every
time-shifted copy of itself (host/workbench/diagnose/null.py), and it is identifiable: its stand-in predicted from
position does not keep most of the gain (host/workbench/diagnose/identify.py). The best such candidate is ranked
first and reported. A finding is added to the model and the
survey diagnosed again, up to `rounds` times.
"""

from __future__ import annotations

import dataclasses
import re
import time

from forcemap.host.progress import Progress
from forcemap.host.workbench.diagnose import identify
from forcemap.host.workbench.diagnose.evaluate import DIAGNOSE_MAX_BASIS, Evaluator
from forcemap.host.workbench.diagnose.null import beats_null, null_gains
from forcemap.host.workbench.diagnose.result import (
    Candidate,
    Diagnosis,
    Round,
    explain_candidate,
)
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey import data_quality
from forcemap.host.workbench.survey.instruments import Instruments
from forcemap.host.workbench.survey.table import NOT_COVARIATES as SKIP
from forcemap.host.workbench.survey.table import Survey, family, is_circular
from forcemap.host.workbench.targets.target_model import SurveyModel, derived_column, survey_inputs
from forcemap.host.workbench.terms import clock_offset, registry
from forcemap.host.workbench.terms.registry import parse_term
from forcemap.host.workbench.timejudge.candidate import (
    fitted_seiche,
    smooth_time_term,
    time_term,
    too_few_note,
)
from forcemap.host.workbench.validation.cv import DEFAULT_FOLDS

__all__ = ["DIAGNOSE_MAX_BASIS", "FLOOR", "diagnose", "Diagnosis", "Candidate"]

# a gain below this is negligible whatever the null says (docs/WORKBENCH.md justifies it)
FLOOR = 0.10
# the identifiability and null tests run for at most this many candidates that pass the floor and the p-value
SCREEN = 4
DEFAULT_ROUNDS = 3
# a proxy gives way to a direct cause that leaves it less than this to add (see _prefer_direct_cause)
PROXY_LEFTOVER = 0.25
# a direct cause within this many places of a leading proxy may take its place
PROXY_WINDOW = 10
ALPHA = 0.05
PROXIES = {"t", "app_wind_angle", "app_wind_speed", "cog", "crab", "throttle"}


def candidate_covariates(survey: Survey, sm: SurveyModel) -> list[str]:
    """Every numeric column outside the target's family, time, and derived ones (heading relative to the flow,
    speed through water)."""
    used = {i for s in sm.term_specs for i in s.inputs}
    fam = sm.vector.family if sm.vector else family(sm.target)
    names = []
    for name in survey.numeric_columns():
        if name in SKIP or name == sm.target or name in used:
            continue
        if fam is not None and family(name) == fam:
            continue
        names.append(name)
    if "t" not in used:
        names.append("t")
    if "heading" in survey.columns:
        for derived in ("heading_rel_current", "heading_rel_wind"):
            if (
                derived not in used
                and derived not in names
                and survey.vector_target(derived.replace("heading_rel_", "") + "_speed")
            ):
                names.append(derived)
    if (
        fam != "current"
        and "stw" not in used
        and "stw" not in names
        and survey.vector_target("current_speed")
        and "sog" in survey.columns
    ):
        names.append("stw")
    if not sm.corrections and clock_offset.applicable(survey, sm.vector):
        names.append(clock_offset.NAME)
    if sm.vector and sm.vector.aspect == "speed":
        own_dir = sm.vector.name.replace("_speed", "_dir")
        if own_dir in survey.columns and own_dir not in used:
            names.append(own_dir)
    return names


def diagnose(
    survey: Survey,
    target: str,
    terms: list[str] | None = None,
    folds: int = DEFAULT_FOLDS,
    seed: int = 0,
    rounds: int = DEFAULT_ROUNDS,
    alpha: float = ALPHA,
    progress: bool = True,
) -> Diagnosis:
    """Diagnose, add what is found, and diagnose again, until nothing more is found or `rounds` are done."""
    if rounds < 1:
        raise WorkbenchError(f"--rounds must be at least 1, not {rounds}")
    terms = list(terms or ["const", "gp(position, matern32)"])
    done: list[Round] = []
    ev = Evaluator(survey, target, terms, folds, seed)
    for i in range(rounds):
        label = f"diagnose {target}" + (f" (round {i + 1})" if i else "")
        r, refit = diagnose_round(survey, ev, alpha, progress, label)
        done.append(r)
        if r.added is None:
            break
        terms = terms + [r.added.term]
        ev = refit or Evaluator(survey, target, terms, folds, seed)
    return Diagnosis(target, done, consistent(data_quality.findings(survey, [target]), done[0]))


def consistent(data: list, first: Round) -> list:
    """The data findings, their advice never pointing to a model term that the diagnosis's own table ranks
    as making the model worse (a latency the clock_offset term does not undo on this survey)."""
    worse = {c.covariate: c for c in first.candidates if c.improvement < 0}
    c = worse.get(clock_offset.NAME)
    if c is None:
        return data
    instead = (
        f"the model term clock_offset does not undo it on this survey (the table below ranks it "
        f"{c.improvement:+.0%}: the map gets worse), so fix it at the source"
    )
    return [
        dataclasses.replace(f, advice=f.advice.replace(data_quality.CLOCK_HINT, instead))
        if f.kind == "latency"
        else f
        for f in data
    ]


def diagnose_round(
    survey: Survey, ev: Evaluator, alpha: float, progress: bool, label: str
) -> tuple[Round, Evaluator | None]:
    """One diagnosis of the model `ev` evaluates: every candidate's gain, ranked, judged; with the
    evaluator of the model that takes the finding's term, where the finding already built it (a time
    finding's figure is the next round's: `Evaluator.as_next_round`)."""
    clock = time.perf_counter()
    target = ev.target
    names = candidate_covariates(survey, ev.sm)
    proxies = identify.time_proxies(survey, [n for n in names if n != "t"])
    names = [n for n in names if n not in proxies]
    results, skipped, evs = _evaluate_all(ev, names, Progress(label, len(names), progress))
    results.sort(key=lambda c: -c.improvement)
    results = _prefer_direct_cause(results, lambda a, b: ev.on_rows_with(a, b).pair_gain(a, b))
    seconds = {"candidates": time.perf_counter() - clock}
    for c in results:
        if c.covariate == "t":
            c.time_proxies = proxies
    threshold = alpha / max(len(results), 1)
    _judge(evs, results, threshold, seconds)
    if any(c.covariate == "t" and c.time is not None and not c.revisit for c in results):
        results.sort(key=lambda c: -c.improvement)  # time now carries its blocks' gain: rank it by that
    results = _evidence_first(results)
    others = [c.covariate for c in results if c.identifiable is False]
    what = _component(ev.sm)
    fam = ev.sm.vector.family if ev.sm.vector else (family(target) or "field")
    inst = Instruments.of(survey)
    for c in results:
        rest = [o for o in others if o != c.covariate]
        w = "" if c.covariate == clock_offset.NAME else what
        c.explanation = explain_candidate(c, w, fam, FLOOR, rest, inst)
    found = bool(results) and results[0].significant
    advice = None
    if results and results[0].identifiable is False:
        advice = identify.advice(results[0].covariate, proxies, results[0].one_pass)
    r = Round(
        target, ev.sm.terms, ev.base_b.rmse, results, found, skipped, advice, proxies, seconds, threshold
    )
    return r, evs[results[0].covariate].refits.get(results[0].term) if found else None


def _evaluate_all(
    ev: Evaluator, names: list[str], bar: Progress
) -> tuple[list[Candidate], dict[str, str], dict[str, Evaluator]]:
    """Every candidate's evaluation, in the order given, each on the rows that have it (and the evaluator
    of those rows, by candidate); the ones that cannot be modelled, with why."""
    results: list[Candidate] = []
    skipped: dict[str, str] = {}
    evs: dict[str, Evaluator] = {}
    for name in names:
        bar.step(name)
        try:
            evs[name] = on = ev.on_rows_with(name)
            c = _evaluate(on, name)
        except WorkbenchError as exc:
            skipped[name] = str(exc)
            continue
        if on is not ev:
            c.rows, c.note = on.survey.n, "; ".join(filter(None, [on.rows_note(ev), c.note]))
        results.append(c)
    bar.close()
    return results, skipped, evs


def _evaluate(ev: Evaluator, name: str) -> Candidate:
    if name == clock_offset.NAME:
        term, rmse, gain, p, sd = ev.clock()
        c = Candidate(name, term, rmse, gain, p, gain, None, False, gain_sd=sd, blocked_sd=sd)
        c.note = clock_offset.scan_offset(ev.sm.survey, ev.sm.vector).edge_note()
        return c
    if name != "t":
        derived_column(ev.survey, name)
    model = ev.extended(name)
    cv, gain_b, p_b = ev.blocked(model)
    sd_b = ev.gain_sd(cv)
    gain, p, gain_r, sd = gain_b, p_b, None, sd_b
    is_consequence = name in ev.consequences
    if is_consequence:
        gain_r, p_r, sd_r = ev.random(model)
        gain, p = min(gain_b, gain_r), max(p_b, p_r)
        sd = sd_r if gain_r < gain_b else sd_b
    spec = str(parse_term(name, is_circular))
    c = Candidate(name, spec, cv.rmse, gain, p, gain_b, gain_r, is_consequence, gain_sd=sd)
    c.blocked_sd = sd_b
    c.hypers = model.theta_
    if name == "t":
        _judged_at_revisits(ev, c)
    return c


def _judged_at_revisits(ev: Evaluator, c: Candidate) -> None:
    """Time judged where the boat comes back too (host/workbench/timejudge/judge.py): the revisits'
    share and p-value become the candidate's, the term is the one their form advises, and the blocked-CV
    figures stay beside them (a short survey's few stretches may judge weakly what its blocks show
    plainly). Nothing changes when the track comes back too little."""
    found = ev.time_verdict()
    if found is None:
        c.note = too_few_note(ev.sm)
        return
    c.blocked_p = c.p_value
    c.take_time_verdict(*found)
    smooth = smooth_time_term(ev.target)
    if smooth != c.term:  # under depth, time is the water level
        cv, c.blocked_gain, c.blocked_p = ev.blocked(ev.with_term(smooth))
        c.term, c.cv_rmse, c.blocked_sd = smooth, cv.rmse, ev.gain_sd(cv)


def _advise_time_term(ev: Evaluator, c: Candidate) -> None:
    """The term a significant verdict's form advises (a tide, a seiche, a drift), with its blocked-CV RMSE
    and gain as the next round will fit it."""
    term = time_term(c.time, ev.target)
    if registry.caps(parse_term(term, is_circular)).estimates_period:
        est = fitted_seiche(ev.sm, c.time)
        if est is not None:
            c.time.fitted_period_s, c.time.fitted_period_sd_s = est.period_s, est.period_sd_s
            term = time_term(c.time, ev.target)
    cv, c.blocked_gain, c.blocked_p = ev.as_next_round(term)
    c.term, c.cv_rmse, c.blocked_sd = term, cv.rmse, ev.gain_sd(cv)


def _judged_on_blocks(c: Candidate) -> None:
    """Time the revisits could not tell but the blocks' rule found (a short survey's few stretches): the
    candidate carries the blocks' gain and p-value, and says what the revisits showed."""
    c.revisit = False
    c.improvement, c.p_value, c.gain_sd = c.blocked_gain, c.blocked_p, c.blocked_sd
    c.why = f"credited on blocks: the revisits alone could not tell (p {c.time.p_value:.1e})"
    c.note = f"judged on blocks: the revisits alone could not tell (p = {c.time.p_value:.2g}; {c.note})"


def _judge(
    evs: dict[str, Evaluator], results: list[Candidate], threshold: float, seconds: dict
) -> None:
    """Mark each candidate significant or not: floor, p-value, null, identifiability (the last two only for
    the few that pass the first two, best first), each on the rows it was evaluated on."""
    t_null = t_ident = 0.0
    screened = 0
    for c in results:
        ev = evs[c.covariate]
        c.significant = False
        gain, p = c.improvement, c.p_value
        said = ["consequence: its random-fold gain"] if c.consequence else []
        if c.revisit:
            # judged at the revisits, where the place is the same and only the time differs: the null is
            # the exchange of whole stretches' times, the significance its p-value, with no floor
            if (found := ev.time_verdict(threshold))[0] is not c.time:  # drawn again near the threshold
                c.take_time_verdict(*found)
            if c.p_value <= threshold:
                c.identifiable, c.significant = True, True
                c.why = f"at {c.time.pairs:,} revisit pairs ({c.time.crossings} crossings)"
                _advise_time_term(ev, c)
                continue
            gain, p = c.blocked_gain, c.blocked_p  # else the blocks' evidence, under their own rule
            said.append(f"revisits p {c.time.p_value:.1e}, then the blocks' rule")
        elif c.covariate == "t":
            said.append("too few revisits, the blocks' rule")
        stop = _screened_out(gain, p, threshold, screened)
        c.why = "; ".join([*said, stop] if stop else said)
        if stop:
            continue
        screened += 1
        if c.covariate == clock_offset.NAME:
            # a correction of the target, not a covariate: nothing to shift, nothing position could predict
            c.identifiable, c.significant = True, True
            c.why = "a correction of the data: beats the blocks' rule"
            continue
        values = survey_inputs(ev.survey, {c.covariate})[c.covariate]
        scale = identify.map_length_scale(ev)
        if identify.is_single_pass(ev.survey, scale):
            c.predictability = identify.smooth_along_track(ev.survey, c.covariate, values, scale)
            if c.predictability >= identify.SMOOTH_SHARE:
                c.identifiable, c.one_pass, c.confounded_with = False, True, ["position"]
                c.why = "stands in for position: one pass"
                continue
        t0 = time.perf_counter()
        stand_in, c.predictability = identify.predict_from_model_inputs(ev, c.covariate, values)
        c.replaced_gain = float(ev.blocked(ev.extended(c.covariate, stand_in))[1])
        t1 = time.perf_counter()
        c.null_gains = null_gains(ev, c.covariate, values, c.hypers)
        t2 = time.perf_counter()
        t_ident, t_null = t_ident + t1 - t0, t_null + t2 - t1
        c.identifiable = c.replaced_gain < identify.REPLACED_SHARE * c.blocked_gain
        if not c.identifiable:
            c.confounded_with = identify.confounders(ev)
        c.significant = c.identifiable and beats_null(gain, c.null_gains)
        c.why = _judged_why(c, said)
    seconds.update(identifiability=t_ident, null=t_null)
    for c in results:
        if c.revisit and c.significant and c.time.p_value > threshold:
            _judged_on_blocks(c)
    _own_direction_after_time(evs, results)


def _screened_out(gain: float, p: float, threshold: float, screened: int) -> str:
    """Why the blocks' rule stops a candidate before its null and identifiability: a gain under the floor,
    a p-value above the threshold, or the null's budget spent on stronger ones; "" when it goes on."""
    if gain < FLOOR:
        return f"under the {FLOOR:.0%} floor"
    if p > threshold:
        return f"p above {threshold:.1e}"
    return f"after the {SCREEN} strongest: not screened" if screened >= SCREEN else ""


def _judged_why(c: Candidate, said: list[str]) -> str:
    """Why a screened candidate is credited or not: what position can tell of it, and its null."""
    if c.identifiable is False:
        got = f"stands in for {', '.join(c.confounded_with)} (it keeps {c.replaced_gain:.0%} replaced)"
    elif not c.significant:
        got = f"time-shifted copies gain {max(c.null_gains, default=0.0):.0%}"
    else:
        got = "beats its time-shifted copies and position's stand-in"
    return "; ".join([*said, got])


def _own_direction_after_time(evs: dict[str, Evaluator], results: list[Candidate]) -> None:
    """A speed target's own direction, and the heading relative to it, are derived from the target: when
    the flow changes in time (a tide or a seiche turns it and changes its strength together), they follow
    that change. Once time is found each is credited only with what it adds to a model with time in it,
    and its row says what it shares with time."""
    t = next((c for c in results if c.covariate == "t" and c.significant), None)
    vt = None if t is None else evs["t"].sm.vector
    if vt is None or vt.aspect != "speed":
        return
    for own in (vt.column("dir"), f"heading_rel_{vt.prefix}"):
        d = next((c for c in results if c.covariate == own and c.improvement > 0), None)
        if d is None:
            continue
        left, left_sd = evs[own].pair("t", own)
        d.note = (
            f"{own} is derived from the target's own direction, and the {vt.prefix} changes in time: "
            f"once time is in the model it adds {left:+.0%} (credited with that)"
        )
        if left < d.improvement:
            d.improvement, d.gain_sd = left, left_sd
        shared = f"derived from the target, shares {max(d.blocked_gain - left, 0.0):.0%} with t"
        d.why = "; ".join(filter(None, [d.why, shared]))
        d.significant = d.significant and d.improvement >= FLOOR


def _evidence_first(results: list[Candidate]) -> list[Candidate]:
    """The best candidate that passes the finding rule goes first: a larger gain with no evidence behind it
    (a few blocks, a p-value far from the threshold) is not a better explanation.

    Time credited at the revisits and a covariate credited on the blocks have gains on two scales (a share
    of the passes' differences, a held-out error): between the two, the smaller p-value leads. On the
    Flensburg race with an injected M2 stream, the heading's +12 % in unseen blocks (p 1.5e-3; +7.6 % on
    the log without the stream) would otherwise lead the stream (p 3.3e-4 at 363 crossings)."""
    lead = next((c for c in results if c.significant), None)
    t = next((c for c in results if c.covariate == "t" and c.significant and c.revisit), None)
    if lead is not None and t is not None and t is not lead and t.p_value < lead.p_value:
        why = f"ranked above {lead.covariate} ({lead.improvement:.0%}, p {lead.p_value:.1e}): stronger evidence"
        t.note, t.why = "; ".join(filter(None, [t.note, why])), "; ".join(filter(None, [t.why, why]))
        return [t] + [c for c in results if c is not t]
    if lead is None or lead is results[0]:
        return results
    above = results[: results.index(lead)]
    names = ", ".join(f"{c.covariate} ({c.improvement:.0%}, p {c.p_value:.1e})" for c in above)
    ranked = f"ranked above {names}: a larger gain that fails the finding rule"
    lead.note = f"{lead.note}; {ranked}" if lead.note else ranked
    return [lead] + [c for c in results if c is not lead]


def _component(sm: SurveyModel) -> str:
    if sm.primary_is_along:
        return "along the flow (speed)"
    return "across the flow (direction)" if sm.vector and sm.circular else ""


def is_proxy(name: str) -> bool:
    """Covariates that stand in for a cause rather than being one: time (everything that changes along the
    track), the apparent wind (speed and angle), course and crab (on straight legs they follow the heading),
    the throttle (a command, set leg by leg: it follows the heading too, and stands in for the speed
    through the water), and the raw paddle-wheel speeds (the boat's speed through water, seen along one
    axis)."""
    return name in PROXIES or re.fullmatch(r"wheel\d+_speed", name) is not None


def _prefer_direct_cause(results: list[Candidate], pair_gain) -> list[Candidate]:
    """If a proxy leads, but a direct covariate close behind leaves the proxy little to add once it is in the
    model, the direct covariate is the explanation and goes first."""
    if not results or not is_proxy(results[0].covariate) or results[0].improvement <= 0:
        return results
    if results[0].revisit:
        return results  # judged at revisits, where no covariate of place can stand in for it
    lead = results[0]
    for i, c in enumerate(results[1:PROXY_WINDOW], start=1):
        if is_proxy(c.covariate) or c.consequence:
            continue  # a consequence of the field is no direct cause (sog reads the current it explains)
        if registry.caps(parse_term(c.covariate, is_circular)).acts_on_data:
            continue  # a correction of the data (a clock offset), not a column a model can take a term in
        if c.improvement < 0.5 * lead.improvement or c.improvement < PROXY_LEFTOVER:
            continue
        if pair_gain(c.covariate, lead.covariate) < PROXY_LEFTOVER:
            c.note = (
                f"ranked above {lead.covariate}: once {c.covariate} is in the model, a term in "
                f"{lead.covariate} adds less than {PROXY_LEFTOVER:.0%}"
            )
            return [c] + [r for j, r in enumerate(results) if j != i]
    return results
