"""The result of `diagnose`: candidates, the rounds of findings, their JSON contract and their text."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from forcemap.host.workbench.diagnose.catalogue import explain, time_form_cause
from forcemap.host.workbench.diagnose.evaluate import DIAGNOSE_MAX_BASIS, REPEATS
from forcemap.host.workbench.diagnose.null import NULL_MARGIN
from forcemap.host.workbench.survey.data_quality import DataFinding
from forcemap.host.workbench.survey.instruments import Instruments
from forcemap.host.workbench.survey.table import unit_of
from forcemap.host.workbench.timejudge.notes import revisit_note
from forcemap.host.workbench.validation.cv import DEFAULT_FOLDS

# which folds the diagnosis's errors come from
FOLD_WORDS = (
    f"blocked {DEFAULT_FOLDS}-fold CV pooled over {REPEATS} assignments of the spatial blocks to folds "
    f"(seeds 0-{REPEATS - 1}), a GP basis of at most {DIAGNOSE_MAX_BASIS} functions"
)


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
    # judged only for candidates that pass the floor and the p-value (None: not judged)
    identifiable: bool | None = None
    confounded_with: list[str] = field(default_factory=list)
    predictability: float | None = None  # blocked-CV R^2 of the candidate from the model's inputs
    replaced_gain: float | None = None  # gain with the candidate replaced by that prediction
    null_gains: list[float] = field(default_factory=list)
    time_proxies: list[str] = field(default_factory=list)  # counters and clocks folded into t
    one_pass: bool = False  # confounded because the survey is one pass (identify.is_single_pass)
    revisit: bool = False  # judged where the boat comes back (diagnose/time_candidate.py)
    time: object = field(default=None, repr=False)  # the revisits' TimeVerdict
    blocked_p: float | None = None  # the blocked-CV p-value, when the revisits' p-value is the candidate's
    rows: int | None = None  # judged on this many rows, those that have it (None: the model's own)
    gain_sd: float = math.nan  # the sd of `improvement` (over the blocks, or the crossings at revisits)
    blocked_sd: float = math.nan  # the sd of `blocked_gain`
    why: str = ""  # why it is credited or not, in a few words (the table's last column)
    hypers: object = field(
        default=None, repr=False
    )  # the extended model's theta, for the null's refits

    def take_time_verdict(self, verdict, held: int) -> None:
        """`t` carries the revisits' verdict (`time_candidate.time_verdict`): its share, its p-value and
        what they showed (`revisit_note`)."""
        self.revisit, self.time = True, verdict
        self.improvement, self.p_value = verdict.improvement, verdict.p_value
        self.gain_sd = verdict.improvement_sd
        self.note = revisit_note(verdict, held)

    def to_json(self) -> dict:
        return {
            "covariate": self.covariate,
            "cv_rmse": self.cv_rmse,
            "improvement": self.improvement,
            "improvement_sd": _finite(self.gain_sd),
            "p_value": _finite(self.p_value),
            "credited": self.significant,
            "why": self.why,
            "explanation": self.explanation,
            "identifiable": self.identifiable,
            "confounded_with": self.confounded_with,
            "null_gains": self.null_gains,
            "rows": self.rows,
            "time": None if self.time is None else dataclasses.asdict(self.time),
        }


def _finite(x: float) -> float | None:
    """A number for the JSON contract: null where it is not finite."""
    return float(x) if math.isfinite(x) else None


@dataclass
class Round:
    """One diagnosis of one model: its candidates, best first, and what it found."""

    target: str
    terms: list[str]
    cv_rmse: float
    candidates: list[Candidate]
    missing_effect_found: bool
    skipped: dict[str, str] = field(default_factory=dict)
    advice: str | None = None
    time_proxies: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)
    threshold: float | None = None  # the p-value a finding needs: alpha over the candidates (Bonferroni)

    @property
    def added(self) -> Candidate | None:
        return self.candidates[0] if self.missing_effect_found else None

    @property
    def closest(self) -> Candidate | None:
        """The candidate with the smallest p-value, when none was found (its p-value above the threshold, or
        below it with the rest of the rule failed: the floor, its nulls, identifiability)."""
        judged = [c for c in self.candidates if math.isfinite(c.p_value)]
        if self.missing_effect_found or not judged or self.threshold is None:
            return None
        return min(judged, key=lambda c: c.p_value)

    def closest_line(self) -> str | None:
        """What the candidate with the smallest p-value showed, when nothing was found, and for a change in
        time the form it would take: a change the data almost show (a level seen at one harbour passed
        twice) is worth a look, and worth a survey, or a gauge, that would settle it."""
        from forcemap.host.workbench.survey.table import family as family_of
        from forcemap.host.workbench.timejudge.candidate import short_for_a_tide

        c = self.closest
        if c is None:
            return None
        alpha = self.threshold * len(self.candidates)
        line = (
            f"  closest: {c.covariate}, the smallest p-value ({c.p_value:.1e}; the threshold is "
            f"{self.threshold:.1e}, {alpha:g} over the {len(self.candidates)} candidates): {c.explanation}"
        )
        if c.time is not None and c.time.share > 0:
            fam = family_of(self.target) or "field"
            line += f" If it is real: {time_form_cause(c.time, fam, short_for_a_tide(c.time))}."
        return line

    def to_json(self) -> dict:
        return {
            "baseline": {"terms": self.terms, "cv_rmse": self.cv_rmse},
            "missing_effect_found": self.missing_effect_found,
            "added": self.added.term if self.added else None,
            "cv_rmse_after": self.added.cv_rmse if self.added else self.cv_rmse,
            "advice": self.advice,
            "threshold": self.threshold,
            "candidates": [c.to_json() for c in self.candidates],
        }

    def lines(self) -> list[str]:
        unit = f" {u}" if (u := unit_of(self.target)) else ""
        out = [
            f"target {self.target}: current model {' + '.join(self.terms)}, blocked-CV RMSE "
            f"{self.cv_rmse:.4g}{unit}",
            f"  ({FOLD_WORDS}; `fit` uses one assignment, seed 0, and a larger GP basis: its RMSE differs)",
        ]
        for name in self.time_proxies:
            out.append(
                f"{name} only counts time (it is monotone in time): it carries the information t carries, "
                "so it is folded into t and never named as a cause"
            )
        if self.missing_effect_found:
            best = self.candidates[0]
            out += [f"missing effect found: {best.covariate}", f"  {best.explanation}"]
        else:
            out.append(
                "no missing effect found: no identifiable covariate beats its null significantly"
            )
            if line := self.closest_line():
                out.append(line)
        if self.advice:
            out.append(f"  survey advice: {self.advice}")
        return out + ["", *self.table()]

    def table(self) -> list[str]:
        """One line per candidate, on one scale: the effect it is credited with (the relative drop of the
        error) and its sd, its p-value, whether it is credited, and why."""
        out = [
            f"{'rank':>4}  {'covariate':<22} {'effect':>7} {'± sd':>6} {'p':>8}  {'credited':<8}  why"
        ]
        for i, c in enumerate(self.candidates, 1):
            why = [c.why] if c.why else []
            if c.rows is not None:
                why.append(f"judged on the {c.rows:,} rows that have it")
            sd = f"{c.gain_sd:>6.1%}" if math.isfinite(c.gain_sd) else f"{'':>6}"
            out.append(
                f"{i:>4}  {c.covariate:<22} {c.improvement:>+7.1%} {sd} {c.p_value:>8.1e}  "
                f"{'yes' if c.significant else 'no':<8}  {'; '.join(why)}"
            )
        return out


@dataclass
class Diagnosis:
    """Every round, in order; the first round's findings are the top-level ones (the stable contract)."""

    target: str
    rounds: list[Round]
    # problems of the log itself, listed ahead of the physics (host/workbench/survey/data_quality.py)
    data: list[DataFinding] = field(default_factory=list)

    @property
    def first(self) -> Round:
        return self.rounds[0]

    @property
    def terms(self) -> list[str]:
        return self.first.terms

    @property
    def cv_rmse(self) -> float:
        return self.first.cv_rmse

    @property
    def candidates(self) -> list[Candidate]:
        return self.first.candidates

    @property
    def missing_effect_found(self) -> bool:
        return self.first.missing_effect_found

    @property
    def skipped(self) -> dict[str, str]:
        return self.first.skipped

    def to_json(self) -> dict:
        """The stable machine-readable contract (docs/WORKBENCH.md documents every key)."""
        first = self.first.to_json()
        rounds = [r.to_json() for r in self.rounds]
        for r, after in zip(rounds, rounds[1:], strict=False):
            if r["added"]:  # the model with the term refitted in full: the next round's own
                r["cv_rmse_after"] = after["baseline"]["cv_rmse"]
        return {
            "target": self.target,
            "baseline": first["baseline"],
            "missing_effect_found": first["missing_effect_found"],
            "candidates": first["candidates"],
            "advice": first["advice"],
            "data_quality": [f.to_json() for f in self.data],
            "rounds": rounds,
        }

    def details(self) -> dict:
        out = self.to_json()
        out["candidate_details"] = [
            {
                k: (dataclasses.asdict(v) if k == "time" and v is not None else v)
                for k, v in c.__dict__.items()
                if k != "hypers"
            }
            for c in self.first.candidates
        ]
        out["skipped"] = self.first.skipped
        out["time_proxies"] = self.first.time_proxies
        out["seconds"] = [r.seconds for r in self.rounds]
        return out

    def steps(self) -> list[str]:
        """The error falling, one line per round."""
        return round_steps(self.to_json())

    def summary(self) -> str:
        lines = []
        if self.data:
            lines.append("data quality (check these before the physics below):")
            lines += [f"  {f.line()}" for f in self.data] + [""]
        for i, r in enumerate(self.rounds, 1):
            if len(self.rounds) > 1:
                lines.append(f"== round {i}")
            lines += r.lines() + [""]
        if len(self.rounds) > 1:
            lines += self.steps()
        return "\n".join(lines).rstrip()


def explain_candidate(
    c: Candidate,
    what: str,
    family: str,
    floor: float,
    others_confounded: list[str],
    instruments: Instruments | None = None,
) -> str:
    """The candidate's line of text: its gain, the verdict and why, a likely cause (naming only the
    survey's own instruments) and a term."""
    cause, term = explain(c.covariate, instruments, family)
    if c.revisit and c.time is not None:
        return explain_time(c, family)
    head = (
        f"adding {c.term}{' ' + what if what else ''} cuts the blocked-CV RMSE by {c.blocked_gain:.0%}"
        if c.blocked_gain >= 0
        else f"adding {c.term} does not help (blocked-CV RMSE {-c.blocked_gain:.0%} worse)"
    )
    if c.time_proxies:
        head += f" ({', '.join(c.time_proxies)} only count time and are folded into t)"
    if c.consequence:
        rg = c.random_gain if c.random_gain is not None else math.nan
        head += (
            f"; it is a consequence of the {family} being mapped, so it is credited only with the gain "
            f"left when the field is known (random folds: {rg:.0%})"
        )
    if c.null_gains:
        head += f"; the same term on time-shifted copies of {c.covariate} gains at most {max(c.null_gains):.0%}"
    if c.identifiable is False and c.one_pass:
        verdict = (
            f"not identifiable: {c.covariate} is confounded with position on this survey, which is one "
            "pass: it is a smooth function of the distance along it (a smoother over the map's length "
            f"scale explains R^2 = {c.predictability:.2f} of it), like the map itself; do not read it "
            "as a cause"
        )
        return f"{head}; p = {c.p_value:.1e}, {verdict}."
    if c.identifiable is False:
        also = f" (so are {', '.join(others_confounded)})" if others_confounded else ""
        verdict = (
            f"not identifiable: {c.covariate} is confounded with {' and '.join(c.confounded_with)} on this "
            f"survey{also}: predicted from them block by block (R^2 = {c.predictability:.2f}) it still gains "
            f"{c.replaced_gain:.0%}, so the gain cannot be told from the map's; do not read it as a cause"
        )
        return f"{head}; p = {c.p_value:.1e}, {verdict}."
    verdict = (
        "significant"
        if c.significant
        else f"not significant (needs a gain >= {floor:.0%}, an error {NULL_MARGIN:.0%} below its best null's, and a small p-value)"
    )
    extra = f" ({c.note})" if c.note else ""
    if c.improvement < 0:  # never suggest a term the table ranks as making the model worse
        return f"{head}; p = {c.p_value:.1e}, {verdict}{extra}."
    return f"{head}; p = {c.p_value:.1e}, {verdict}{extra}. Likely cause: {cause}. Suggested term: {term}."


def round_steps(diagnosis_json: dict) -> list[str]:
    """One line per round of a diagnosis (its JSON, as saved in the workspace): what was added and the error
    falling. A diagnosis saved before rounds existed is its own single round."""
    rounds = diagnosis_json.get("rounds") or [
        {**diagnosis_json, "added": None, "cv_rmse_after": diagnosis_json["baseline"]["cv_rmse"]}
    ]
    out = []
    unit = f" {u}" if (u := unit_of(diagnosis_json.get("target", ""))) else ""
    for i, r in enumerate(rounds, 1):
        before = r["baseline"]["cv_rmse"]
        step = f"round {i}: blocked-CV RMSE {before:.4g}{unit}"
        if r.get("added"):
            after = r["cv_rmse_after"]
            fall = 1.0 - after / before if before > 0 else 0.0
            change = f"{fall:.0%} lower" if fall >= 0 else f"{-fall:.0%} higher"
            step += f" -> {after:.4g}{unit} with {r['added']} ({change})"
        else:
            step += ": nothing more found" + (
                f"; survey advice: {r['advice']}" if r.get("advice") else ""
            )
        out.append(step)
    return out


def explain_time(c: Candidate, family: str) -> str:
    """Time's line when the revisits judged it: what they showed, how sure, its form and its term."""
    from forcemap.host.workbench.timejudge.candidate import short_for_a_tide

    v = c.time
    head = (
        f"where the boat comes back, a change in time explains {v.share:.0%} of the differences between "
        f"passes (their RMS falls by {c.improvement:.0%}; in unseen blocks adding {c.term} gains "
        f"{c.blocked_gain:+.0%})"
    )
    null = (
        f"p = {c.p_value:.1e} against {v.permutations} exchanges of whole stretches' times "
        "(their own noise and correlation kept)"
    )
    if not c.significant:
        return f"{head}; {null}: not significant ({c.note})."
    cause = time_form_cause(v, family, short_for_a_tide(v))
    return f"{head}; {null}: significant ({c.note}). Likely cause: {cause}. Suggested term: {c.term}."
