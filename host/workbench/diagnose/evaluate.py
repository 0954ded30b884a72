"""Measure what one more term buys: the current model of a target plus a term in a covariate, cross-validated.

`Evaluator` holds one survey's current model, its folds and its held-out errors, and answers for any
covariate (its own values, or stand-in values for the null and the identifiability tests) the blocked-CV
gain, the paired p-value and, for a consequence of the field being mapped, the random-fold gain.
"""

from __future__ import annotations

import math

import numpy as np
from forcemap.host.workbench.engine.model import Model, term_inputs
from forcemap.host.workbench.survey.table import KINEMATIC, Survey, family, is_circular
from forcemap.host.workbench.survey.target_rows import target_rows
from forcemap.host.workbench.targets.survey_fits import survey_fits
from forcemap.host.workbench.targets.target_model import SurveyModel, survey_inputs
from forcemap.host.workbench.terms import clock_offset
from forcemap.host.workbench.terms.registry import build_term, parse_term
from forcemap.host.workbench.validation.cv import (
    CVResult,
    gain_sd,
    paired_test,
    random_folds,
    repeated_blocked_folds,
)

# the comparison between candidates needs no finer spatial basis than this; `fit` goes further
DIAGNOSE_MAX_BASIS = 600
# blocked CV is repeated over this many assignments of the blocks to folds (cv.repeated_blocked_folds): with
# one, a weak effect's gain swung between 6 % and 23 % with the assignment, on the same survey
REPEATS = 3


def consequences_of(target: str) -> set[str]:
    """Kinematic covariates that respond to a wind or current target (see diagnose's docstring)."""
    return set(KINEMATIC) if family(target) in ("wind", "current") else set()


class Evaluator:
    """The current model of `target` on `survey`, its blocked and random folds, and its held-out errors."""

    def __init__(
        self,
        survey: Survey,
        target: str,
        terms: list[str],
        folds: int,
        seed: int,
        rows_with: tuple[str, ...] = (),
        like: Evaluator | None = None,
    ) -> None:
        """`rows_with`: covariates whose rows the model is fitted on too; `like`: the evaluator of the
        same model on more rows, whose hyperparameters it keeps (no optimiser: the same field)."""
        self.target = target
        self.given = (survey, terms, folds, seed)
        sm = SurveyModel(survey, target, terms, max_basis=DIAGNOSE_MAX_BASIS, rows_with=rows_with)
        if like is None:
            self.sm = sm.fit()
        else:
            survey_fits(sm.survey).saved.update(survey_fits(like.sm.survey).shared_hypers())
            p = like.sm.primary
            self.sm = sm.fit(theta=p.theta_, n_basis=p.n_basis_)
        # the rows the model is fitted on: the target there, its spikes left out, every covariate there
        # (the clock correction is the model's own business)
        self.survey = survey = self.sm.rows.survey
        self._on_rows: dict[bytes, Evaluator] = {}
        self.fold_ids, self.blocks = repeated_blocked_folds(survey.xy, folds, seed, REPEATS)
        # the paired unit of every blocked comparison: the block, over all its assignments
        self.groups = np.tile(self.blocks, REPEATS)
        self.rfold = random_folds(survey.n, folds, seed)
        self.sec_b: list = [None] * REPEATS
        self.sec_r = None
        if self.sm.secondary is not None:
            sec = self.sm.secondary
            self.sec_b = [sec.cv_predict(f, return_std=False) for f in self.fold_ids]
            self.sec_r = sec.cv_predict(self.rfold, return_std=False)
        self.base_b = self.blocked_cv(self.sm)
        self._base_r: CVResult | None = None
        self._time: tuple | None = None
        # models with one more term, fitted as the next round fits them (`as_next_round`), by that term
        self.refits: dict[str, Evaluator] = {}
        self.consequences = consequences_of(target)

    def on_rows_with(self, *names: str) -> Evaluator:
        """This evaluator, or one on the rows that have the candidates `names` where they miss some of
        these rows for longer than their correlation time: the current model refitted there, so that a
        candidate is judged on the rows that have it, against the same model on the same rows."""
        survey, terms, folds, seed = self.given
        needs = set(self.sm.rows.covariates)
        for name in names:
            needs |= set(clock_offset.AUTOPILOT_COLUMNS) if name == clock_offset.NAME else {name}
        rows = target_rows(survey, self.target, needs)
        if rows.n == self.survey.n:  # a subset of these rows as large as they are: the same rows
            return self
        key = rows.survey.origin[1].tobytes()
        if key not in self._on_rows:
            extra = tuple(sorted(needs - set(self.sm.rows.covariates)))
            self._on_rows[key] = Evaluator(survey, self.target, terms, folds, seed, extra, self)
        return self._on_rows[key]

    def rows_note(self, base: Evaluator) -> str:
        """How the rows this evaluator judges on differ from `base`'s, in words."""
        left = [
            f"{g.count:,} without {name} ({g.where()})"
            for name, g in self.sm.rows.left.items()
            if name not in base.sm.rows.left
        ]
        return (
            f"judged on the {self.survey.n:,} of {base.survey.n:,} rows that have it ("
            + "; ".join(left)
            + ": gaps longer than its correlation time), the current model refitted on them with "
            "its hyperparameters"
        )

    @property
    def fold_id(self) -> np.ndarray:
        """The first assignment: the one the identifiability stand-in is predicted on."""
        return self.fold_ids[0]

    def blocked_cv(self, sm: SurveyModel, primary: Model | None = None) -> CVResult:
        """Held-out predictions of `sm` (with `primary` in place of its own) over every fold assignment.
        Another survey's model (the clock-corrected one) predicts its own secondary."""
        secondaries = self.sec_b if sm is self.sm else [None] * REPEATS
        return CVResult.concat(
            [
                sm.cv(f, primary=primary, secondary_cv=s, interval=False)
                for f, s in zip(self.fold_ids, secondaries, strict=True)
            ]
        )

    @property
    def base_r(self) -> CVResult:
        if self._base_r is None:
            self._base_r = self.sm.cv(self.rfold, secondary_cv=self.sec_r, interval=False)
        return self._base_r

    def inputs(self, name: str, values: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """The current model's inputs plus the covariate `name` (its own values unless `values` is given)."""
        X = dict(self.sm.X)
        X.update(survey_inputs(self.survey, {name}) if values is None else {name: values})
        return X

    def extended(self, name: str, values: np.ndarray | None = None) -> Model:
        """The current model plus the covariate's default term, every hyperparameter refitted: with the spatial
        GP's fixed, a covariate that should take over from it is missed (depth for a Manning current: -10 %
        against +58 %)."""
        term = build_term(parse_term(name, is_circular), is_circular)
        return self.sm.primary.extended(term, self.inputs(name, values), self.sm.y_primary)

    def with_fixed_hypers(self, name: str, values: np.ndarray, theta: np.ndarray) -> Model:
        """The current model plus a term in `values` with the hyperparameters `theta` of an extended model:
        only the new features' cross products and the weights are computed (the null's cheap refit)."""
        term = build_term(parse_term(name, is_circular), is_circular)
        X = self.inputs(name, values)
        Z = term_inputs(term, X)
        term.setup(Z)
        p = self.sm.primary
        design = p.design_.augment(term.features(Z))
        feat = [t for t in p.terms_ if not t.is_mean]
        mean = [t for t in p.terms_ if t.is_mean]
        model = Model(
            feat + [term] + mean, hyper_spacing_s=p.hyper_spacing_s, init=theta, optimize=False
        )
        return model.fit_design(X, self.sm.y_primary, design)

    def blocked(self, model: Model) -> tuple[CVResult, float, float]:
        """Held-out predictions with `model` as the primary, its blocked-CV gain and p-value."""
        cv = self.blocked_cv(self.sm, model)
        gain, p = paired_test(self.base_b.error**2, cv.error**2, self.groups)
        return cv, gain, p

    def gain_sd(self, cv: CVResult) -> float:
        """The sd of `blocked`'s gain for held-out predictions `cv` (the block the paired unit)."""
        return gain_sd(self.base_b.error**2, cv.error**2, self.groups)

    def random(self, model: Model) -> tuple[float, float, float]:
        """Gain, p-value and the gain's sd of `model` on random folds, where the field around every held-out
        sample is known."""
        cv = self.sm.cv(self.rfold, primary=model, secondary_cv=self.sec_r, interval=False)
        base_sq, cand_sq = self.base_r.error**2, cv.error**2
        return (*paired_test(base_sq, cand_sq, self.blocks), gain_sd(base_sq, cand_sq, self.blocks))

    def with_term(self, term: str) -> Model:
        """The current model plus the term `term` (written as a user writes it: `water_level`, `tide`,
        `gp(t, matern32)`), every hyperparameter refitted."""
        spec = parse_term(term, is_circular)
        X = self.inputs("t")
        for name in spec.inputs:
            if name not in X:
                X.update(survey_inputs(self.survey, {name}))
        return self.sm.primary.extended(build_term(spec, is_circular), X, self.sm.y_primary)

    def as_next_round(self, term: str) -> tuple[CVResult, float, float]:
        """`blocked` for the current model with `term`, fitted as the next round fits the model that takes
        it (every hyperparameter searched, a basis grown where its lengthscale needs more): what a finding's
        advice gives. `extended` starts from this model's values with the new term's default basis, which a
        GP in time over hours can leave at a lengthscale its basis barely resolves, with the largest variance
        allowed (on the Geneva seiche: -49 % where the next round's model gains +15 %)."""
        survey, terms, folds, seed = self.given
        nxt = Evaluator(survey, self.target, [*terms, term], folds, seed)
        if nxt.survey.n != self.survey.n:  # other rows (a candidate's): compare on this model's own
            return self.blocked(self.with_term(term))
        self.refits[term] = nxt  # the next round's model, if this term is the finding
        gain, p = paired_test(self.base_b.error**2, nxt.base_b.error**2, self.groups)
        return nxt.base_b, gain, p

    def time_verdict(self, threshold: float | None = None):
        """What the revisits say about time (`time_candidate.time_verdict`), computed once; again with more
        permutations when a `threshold` lies within its p-value's sampling error."""
        from forcemap.host.workbench.timejudge.candidate import time_verdict
        from forcemap.host.workbench.timejudge.judge import undecided

        if self._time is None:
            self._time = (time_verdict(self.sm),)
        found = self._time[0]
        if threshold is not None and found is not None:
            v = found[0]
            if undecided(v.p_value, v.permutations, threshold):
                self._time = (time_verdict(self.sm, threshold=threshold),)
        return self._time[0]

    def clock(self) -> tuple[str, float, float, float, float]:
        """(term, cv_rmse, gain, p, the gain's sd) of correcting a clock offset between the boat-frame
        reading and the heading and ground velocity.

        The offset acts in turns wherever they are, not at places: the paired unit is a stretch of track
        about one turn long, not a spatial block."""
        sm = self.sm
        corrected, tau = clock_offset.corrected_for(sm.survey, sm.vector, math.nan)
        # the same field on the same rows: the current model's hyperparameters, not a new search
        survey_fits(corrected).saved.update(survey_fits(sm.survey).shared_hypers())
        model = SurveyModel(corrected, self.target, sm.terms, max_basis=DIAGNOSE_MAX_BASIS)
        model.fit(theta=sm.primary.theta_, n_basis=sm.primary.n_basis_)
        cv = self.blocked_cv(model)
        stretches = (self.survey.trel // clock_offset.PAIRED_STRETCH_S).astype(int)
        paired = (self.base_b.error**2, cv.error**2, np.tile(stretches, REPEATS))
        gain, p = paired_test(*paired)
        return clock_offset.describe(tau), cv.rmse, gain, p, gain_sd(*paired)

    def pair_gain(self, first: str, then: str) -> float:
        """Blocked-CV gain of adding `then` to the model that already has `first`."""
        return self.pair(first, then)[0]

    def pair(self, first: str, then: str) -> tuple[float, float]:
        """Blocked-CV gain of adding `then` to the model that already has `first`, and the gain's sd."""
        X = dict(self.sm.X)
        X.update(survey_inputs(self.survey, {first, then}))
        y = self.sm.y_primary
        a = self.sm.primary.extended(build_term(parse_term(first, is_circular), is_circular), X, y)
        ab = a.extended(build_term(parse_term(then, is_circular), is_circular), X, y)
        cv_a, cv_ab = self.blocked_cv(self.sm, a), self.blocked_cv(self.sm, ab)
        a_sq, ab_sq = cv_a.error**2, cv_ab.error**2
        return paired_test(a_sq, ab_sq, self.groups)[0], gain_sd(a_sq, ab_sq, self.groups)
