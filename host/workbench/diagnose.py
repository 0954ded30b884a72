"""Find the missing effect: add a term in each candidate covariate, measure the blocked-CV gain, rank and test.

Causes and consequences. The boat's kinematics (sog, cog, crab = heading - cog, yaw_rate, throttle) respond to
the current and wind that push it: at a held-out place they carry information about the very field being
mapped, so in spatially blocked CV they "predict" it although no effect is missing. A genuine instrument error
that grows with boat speed, or appears in turns, is different: it is there even where the field is known. So a
kinematic covariate of a wind or current target is credited only with the gain that survives random
(interleaved) folds, where every held-out sample has measured neighbours and the field is known: the smaller of
its blocked and random-fold gains, and the larger of the two p-values. Causes (depth, time, heading, ...) are
credited with their blocked-CV gain.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from forcemap.host.workbench import clock_offset
from forcemap.host.workbench.catalogue import explain
from forcemap.host.workbench.cv import DEFAULT_FOLDS, blocked_folds, paired_test, random_folds
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.progress import Progress
from forcemap.host.workbench.spec import build_term, parse_term
from forcemap.host.workbench.table import KINEMATIC, Survey, family, is_circular
from forcemap.host.workbench.table import NOT_COVARIATES as SKIP
from forcemap.host.workbench.targets import SurveyModel, derived_column, survey_inputs

MIN_GAIN = 0.25
# a direct cause within this many places of a leading proxy may take its place (see _prefer_direct_cause)
PROXY_WINDOW = 10
# the comparison between candidates needs no finer spatial basis than this; `fit` goes further
DIAGNOSE_MAX_BASIS = 600
ALPHA = 0.05
PROXIES = {"t", "app_wind_angle", "app_wind_speed", "cog", "crab"}


@dataclass
class Candidate:
    covariate: str
    term: str
    cv_rmse: float
    improvement: float
    p_value: float
    blocked_gain: float
    random_gain: float | None
    consequence: bool
    explanation: str = ""
    significant: bool = False
    note: str = ""


@dataclass
class Diagnosis:
    target: str
    terms: list[str]
    cv_rmse: float
    candidates: list[Candidate]
    missing_effect_found: bool
    skipped: dict[str, str] = field(default_factory=dict)

    def to_json(self) -> dict:
        """The stable machine-readable contract."""
        return {
            "target": self.target,
            "baseline": {"terms": self.terms, "cv_rmse": self.cv_rmse},
            "missing_effect_found": self.missing_effect_found,
            "candidates": [
                {
                    "covariate": c.covariate,
                    "cv_rmse": c.cv_rmse,
                    "improvement": c.improvement,
                    "explanation": c.explanation,
                }
                for c in self.candidates
            ],
        }

    def details(self) -> dict:
        out = self.to_json()
        out["candidate_details"] = [c.__dict__ for c in self.candidates]
        out["skipped"] = self.skipped
        return out

    def summary(self) -> str:
        lines = [
            f"target {self.target}: current model {' + '.join(self.terms)}, blocked-CV RMSE {self.cv_rmse:.4g}"
        ]
        if self.missing_effect_found:
            best = self.candidates[0]
            lines.append(f"missing effect found: {best.covariate}")
            lines.append(f"  {best.explanation}")
        else:
            lines.append(
                "no missing effect found: no covariate improves the blocked-CV error significantly"
            )
        lines.append("")
        lines.append(f"{'rank':>4}  {'covariate':<22} {'cv_rmse':>9} {'gain':>7} {'p':>8}  note")
        for i, c in enumerate(self.candidates, 1):
            note = "consequence: credited with its random-fold gain" if c.consequence else ""
            mark = "*" if c.significant else " "
            lines.append(
                f"{i:>4}{mark} {c.covariate:<22} {c.cv_rmse:>9.4g} {c.improvement:>+7.1%} {c.p_value:>8.1e}  {note}"
            )
        return "\n".join(lines)


def consequences_of(target: str) -> set[str]:
    """Kinematic covariates that respond to a wind or current target (see the module docstring)."""
    return set(KINEMATIC) if family(target) in ("wind", "current") else set()


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
    if sm.clock_offset is None and clock_offset.applicable(survey, sm.vector):
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
    min_gain: float = MIN_GAIN,
    alpha: float = ALPHA,
    progress: bool = True,
) -> Diagnosis:
    sm = SurveyModel(survey, target, terms, max_basis=DIAGNOSE_MAX_BASIS).fit()
    fold_id, blocks = blocked_folds(survey.xy, folds, seed)
    rfold = random_folds(survey.n, folds, seed)
    sec_b = sec_r = None
    if sm.secondary is not None:
        sec_b = sm.secondary.cv_predict(fold_id)
        sec_r = sm.secondary.cv_predict(rfold)
    base_b = sm.cv(fold_id, secondary_cv=sec_b)
    consequences = consequences_of(target)
    names = candidate_covariates(survey, sm)
    bar = Progress(f"diagnose {target}", len(names), progress)
    state = {"base_r": None}

    def evaluate(name: str) -> Candidate:
        # every hyperparameter is refitted: with the spatial GP's fixed, a covariate that should take over
        # from it is missed (depth for a Manning current: -10 % against +58 %)
        spec = parse_term(name, is_circular)
        X = dict(sm.X)
        X.update(survey_inputs(survey, {name}))
        model = sm.primary.extended(build_term(spec, is_circular), X, sm.y_primary)
        cv_b = sm.cv(fold_id, primary=model, secondary_cv=sec_b)
        gain_b, p_b = paired_test(base_b.error**2, cv_b.error**2, blocks)
        gain, p, gain_r = gain_b, p_b, None
        is_consequence = name in consequences
        if is_consequence:
            if state["base_r"] is None:
                state["base_r"] = sm.cv(rfold, secondary_cv=sec_r)
            cv_r = sm.cv(rfold, primary=model, secondary_cv=sec_r)
            gain_r, p_r = paired_test(state["base_r"].error ** 2, cv_r.error**2, blocks)
            gain, p = min(gain_b, gain_r), max(p_b, p_r)
        return Candidate(name, str(spec), cv_b.rmse, gain, p, gain_b, gain_r, is_consequence)

    def evaluate_clock() -> Candidate:
        # the offset acts in turns wherever they are, not at places: the paired unit is a stretch of track
        # about one turn long, not a spatial block
        corrected, tau = clock_offset.corrected_for(sm.survey, sm.vector, math.nan)
        model = SurveyModel(corrected, target, sm.terms, max_basis=DIAGNOSE_MAX_BASIS).fit()
        cv_b = model.cv(fold_id)
        stretches = (survey.trel // clock_offset.PAIRED_STRETCH_S).astype(int)
        gain, p = paired_test(base_b.error**2, cv_b.error**2, stretches)
        return Candidate(
            clock_offset.NAME, clock_offset.describe(tau), cv_b.rmse, gain, p, gain, None, False
        )

    def evaluate_pair(first: str, then: str) -> float:
        """Blocked-CV gain of adding `then` to the model that already has `first`."""
        X = dict(sm.X)
        X.update(survey_inputs(survey, {first, then}))
        a = sm.primary.extended(
            build_term(parse_term(first, is_circular), is_circular), X, sm.y_primary
        )
        ab = a.extended(build_term(parse_term(then, is_circular), is_circular), X, sm.y_primary)
        cv_a = sm.cv(fold_id, primary=a, secondary_cv=sec_b)
        cv_ab = sm.cv(fold_id, primary=ab, secondary_cv=sec_b)
        return paired_test(cv_a.error**2, cv_ab.error**2, blocks)[0]

    results: list[Candidate] = []
    skipped: dict[str, str] = {}
    for name in names:
        bar.step(name)
        try:
            if name == clock_offset.NAME:
                results.append(evaluate_clock())
                continue
            if name != "t":
                derived_column(survey, name)
            results.append(evaluate(name))
        except WorkbenchError as exc:
            skipped[name] = str(exc)
    results.sort(key=lambda c: -c.improvement)
    results = _prefer_direct_cause(results, evaluate_pair, min_gain)
    bar.close()
    threshold = alpha / max(len(results), 1)
    for c in results:
        c.significant = c.improvement >= min_gain and c.p_value <= threshold
        c.explanation = _explain(c, sm)
    found = bool(results) and results[0].significant
    return Diagnosis(target, sm.terms, base_b.rmse, results, found, skipped)


def is_proxy(name: str) -> bool:
    """Covariates that stand in for a cause rather than being one: time (everything that changes along the
    track), the apparent wind (speed and angle), course and crab (on straight legs they follow the heading),
    and the raw paddle-wheel speeds (the boat's speed through water, seen along one axis)."""
    return name in PROXIES or re.fullmatch(r"wheel\d+_speed", name) is not None


def _prefer_direct_cause(
    results: list[Candidate], evaluate_pair, min_gain: float
) -> list[Candidate]:
    """If a proxy leads, but a direct covariate close behind leaves the proxy nothing to add once it is in the
    model, the direct covariate is the explanation and goes first."""
    if not results or not is_proxy(results[0].covariate) or results[0].improvement <= 0:
        return results
    lead = results[0]
    for i, c in enumerate(results[1:PROXY_WINDOW], start=1):
        if is_proxy(c.covariate):
            continue
        if c.improvement < 0.5 * lead.improvement or c.improvement < min_gain:
            continue
        if evaluate_pair(c.covariate, lead.covariate) < min_gain:
            c.note = (
                f"ranked above {lead.covariate}: once {c.covariate} is in the model, a term in "
                f"{lead.covariate} adds less than {min_gain:.0%}"
            )
            return [c] + [r for j, r in enumerate(results) if j != i]
    return results


def _explain(c: Candidate, sm: SurveyModel) -> str:
    cause, term = explain(c.covariate)
    what = (
        ""
        if c.covariate == clock_offset.NAME
        else "along the flow (speed)"
        if sm.primary_is_along
        else ("across the flow (direction)" if sm.vector and sm.circular else "")
    )
    head = (
        f"adding {c.term}{' ' + what if what else ''} cuts the blocked-CV RMSE by {c.blocked_gain:.0%}"
        if c.blocked_gain >= 0
        else f"adding {c.term} does not help (blocked-CV RMSE {-c.blocked_gain:.0%} worse)"
    )
    if c.consequence:
        rg = c.random_gain if c.random_gain is not None else math.nan
        head += (
            f"; it is a consequence of the {sm.vector.family if sm.vector else 'field'} being mapped, so it is "
            f"credited only with the gain left when the field is known (random folds: {rg:.0%})"
        )
    verdict = (
        "significant"
        if c.significant
        else f"not significant (needs a gain >= {MIN_GAIN:.0%} and a small p-value)"
    )
    extra = f" ({c.note})" if c.note else ""
    return f"{head}; p = {c.p_value:.1e}, {verdict}{extra}. Likely cause: {cause}. Suggested term: {term}."
