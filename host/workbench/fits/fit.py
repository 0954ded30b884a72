"""Fit a target on a survey, cross-validate it, describe where it fails, and record it in the workspace."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from forcemap.host.extras import install_hint
from forcemap.host.progress import note
from forcemap.host.workbench.depth.water_level import crossline_errors, crossline_rmse
from forcemap.host.workbench.engine import nufft
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.fits.workspace import record_fit, workspace_dir
from forcemap.host.workbench.survey.table import Survey, is_circular, unit_of
from forcemap.host.workbench.targets.survey_fits import survey_fits
from forcemap.host.workbench.targets.target_model import SurveyModel, hyper_rows
from forcemap.host.workbench.terms import registry, time_terms
from forcemap.host.workbench.terms.spec import BASELINE, read_spec_file, split_effects
from forcemap.host.workbench.timejudge.level_check import LevelCheck, check_level
from forcemap.host.workbench.timejudge.revisits import target_radius
from forcemap.host.workbench.validation.cv import (
    DEFAULT_FOLDS,
    Calibration,
    CVResult,
    blocked_folds,
    random_folds,
)
from forcemap.host.workbench.validation.failures import failure_summary

# from this many rows on, the Gram tables' direct sums cost more than the rest of a fit (host/workbench/engine/nufft.py)
BIG_TABLE = 100_000


def resolve_terms(
    model: str | None, effects: str | None, target: str | None
) -> tuple[list[str], str | None]:
    """Terms from a TOML spec (or the paper's baseline), plus `--effects`; and the spec's target, if any."""
    terms, spec_target = read_spec_file(model) if model else (list(BASELINE), None)
    terms = terms + [e for e in split_effects(effects) if e not in terms]
    return terms, target or spec_target


def make_folds(survey: Survey, kind: str, k: int = DEFAULT_FOLDS, seed: int = 0) -> np.ndarray:
    return (
        blocked_folds(survey.xy, k, seed)[0]
        if kind == "blocked"
        else random_folds(survey.n, k, seed)
    )


@dataclass
class FitResult:
    model: SurveyModel
    cv: CVResult
    folds: str
    failures: list[str]
    # the held-out error where the track revisits itself (water_level.crossline_rmse), or None
    crossline: dict | None = None
    # a depth model's level against the same error without it (level_check.check_level), or None
    level: LevelCheck | None = None

    def to_json(self) -> dict:
        """The stable machine-readable contract."""
        out = {
            "target": self.model.target,
            "terms": self.model.terms,
            "cv_rmse": self.cv.rmse,
            "cv_mae": self.cv.mae,
            "coverage95": self.cv.coverage95,
            "calibration": cal.to_json() if (cal := self.model.calibration) else None,
            "spikes": self.model.spikes.to_json() if self.model.spikes else None,
            "gaps": self.model.rows.to_json(),
        }
        if self.model.time_terms:
            out["time_terms"] = time_terms.tide_summary(self.model)
        if self.level is not None:
            out["level_check"] = self.level.to_json()
        return out | (self.crossline or {})

    def summary(self) -> str:
        m = self.model
        unit = f" {u}" if (u := unit_of(m.target)) else ""
        lines = [
            f"target {m.target} ({m.survey.n} samples{', modelled through its east/north components' if m.secondary is not None else ''})",
            f"model  {' + '.join(m.terms)}",
            f"{fold_words(self.folds)}: RMSE {self.cv.rmse:.4g}{unit}, MAE {self.cv.mae:.4g}{unit}",
        ]
        if self.crossline is not None:
            lines.append(
                f"where the track revisits itself ({self.crossline['crossline_samples']} samples, each "
                f"time stretch held out): RMSE {self.crossline['crossline_rmse']:.4g}{unit}"
            )
        if self.level is not None:
            lines.append(f"level: {self.level.line()}")
        if m.calibration is not None:
            lines.append(m.calibration.line())
        lines += [f"gaps: {t}" for t in m.rows.lines()]
        if self.model.spikes is not None:
            lines += [f"spikes: {t}" for t in self.model.spikes.lines()] or [
                "spikes: none flagged along the track"
            ]
        if self.folds == "random":
            lines.append(
                "  (random folds put along-track neighbours in the training set: they flatter every model)"
            )
        lines.append("fitted parameters:")
        for term, params in m.primary.params_.items():
            lines.append(f"  {term}: " + ", ".join(with_units(term, params, m.target)))
        lines += time_terms.describe(m)
        lines.append("where the model fails most (held-out residuals):")
        lines += [f"  {s}" for s in self.failures]
        return "\n".join(lines)


def fold_words(kind: str) -> str:
    """Which folds a CV used, in words (fit's and diagnose's errors differ by their folds; both say so)."""
    if kind == "random":
        return f"random {DEFAULT_FOLDS}-fold CV (seed 0)"
    return f"blocked {DEFAULT_FOLDS}-fold CV (one assignment of the spatial blocks, seed 0)"


def with_units(term: str, params: dict[str, float], target: str) -> list[str]:
    """`name=value unit` for a term's fitted parameters: spreads, levels and amplitudes in the target's
    unit, a GP's lengthscale in its inputs' (m for position), a slope in target unit per input unit."""
    tu = unit_of(target)
    inputs = term[term.find("(") + 1 : term.find(")")].split(",") if "(" in term else []
    kernels = {"linear", "rbf", "matern12", "matern32", "matern52", "periodic"}
    iu = {unit_of(i.strip()) for i in inputs if i.strip() and i.strip() not in kernels}
    iu.discard("")
    out = []
    for k, v in params.items():
        if (
            k in ("std", "value", "amplitude")
            or k.startswith("amplitude_")
            or k.endswith("_amplitude")
        ):
            u = tu
        elif k.endswith("_deg") or k.startswith("phase_deg"):
            u = "deg"
        elif k == "period_s":
            u = "s"
        elif k == "lengthscale":
            u = next(iter(iu)) if len(iu) == 1 else ""
        elif k.startswith("slope_"):
            iun = unit_of(k[len("slope_") :])
            u = f"{tu or '1'}/{iun}" if iun else tu
        else:
            u = ""
        out.append(f"{k}={v:.4g}{' ' + u if u else ''}")
    return out


def fit_target(
    survey: Survey,
    target: str,
    terms: list[str],
    folds: str = "blocked",
    progress: bool = True,
    max_basis: int | None = None,
) -> FitResult:
    rows = hyper_rows(survey)
    hyper = ""
    if rows is not None:
        every = float(np.ptp(survey.trel)) / len(rows)
        hyper = f" (hyperparameters from {len(rows)} of them, one per {every:.1f} s)"
    note(f"fitting {target}: {' + '.join(terms)} on {survey.n} samples{hyper} ...", progress)
    if survey.n >= BIG_TABLE and not nufft.available():
        note(f"(a table this long fits several times faster with finufft: {install_hint('nufft')})", progress)
    sm = SurveyModel(survey, target, terms, max_basis=max_basis)
    fold_ids = make_folds(sm.rows.survey, folds)  # on the rows the model is fitted on
    # the Gram matrices are accumulated fold by fold: the CV then costs no second pass over the data
    survey_fits(sm.rows.survey).grams.plan = fold_ids
    sm.fit()
    note(f"cross-validating ({folds} folds) ...", progress)
    cv = sm.cv(fold_ids)
    if folds == "blocked":  # the maps' band is calibrated on blocked folds only
        sm.calibrate(fold_ids, cv)
    unit = f" {u}" if (u := unit_of(target)) else ""
    # depth is read from the moving surface: what blocked CV cannot see shows where the track crosses itself
    radius = target_radius(sm)
    errors = crossline_errors(sm, radius)
    crossline = crossline_rmse(sm, radius, errors)
    level = check_level(sm, radius, errors, progress)
    failures = failure_summary(sm.survey, cv.error, unit)
    return FitResult(sm, cv, folds, failures, crossline, level)


def record(table: Path, result: FitResult) -> dict:
    """Save the fit in the survey workspace and append it to the history."""
    ws = workspace_dir(table)
    m = result.model
    model = {
        "params": m.primary.params_,
        "theta": [float(v) for v in m.primary.theta_],
        "n_basis": m.primary.n_basis_,
        "log_marginal_likelihood": m.primary.log_marginal_likelihood_,
        "n": m.survey.n,
        # the flow frame and the other component of a vector: a map rebuilt later needs no optimiser
        "shared": survey_fits(m.survey).shared_hypers(),
        # the predictive band's held-out coverage: a map rebuilt later needs no CV
        "calibration": m.calibration.to_json() if m.calibration else None,
    }
    entry = {
        k: v
        for k, v in result.to_json().items()
        if k not in ("spikes", "calibration", "gaps", "time_terms")
    }
    entry.update(folds=result.folds, n=m.survey.n)
    if m.spikes is not None:
        entry["spikes_flagged"] = m.spikes.count
    return record_fit(ws, entry, model)


def saved_model(ws: Path, entry: dict, survey: Survey) -> dict | None:
    """The saved model of a history entry (what `record` wrote), if it can rebuild the fit on `survey`
    (the rows the model is fitted on): the file is there and readable, it has the basis sizes, and it
    was fitted on as many rows."""
    try:
        model = json.loads((ws / entry["model_file"]).read_text())
    except (KeyError, OSError, json.JSONDecodeError):
        return None
    keys = ("theta", "n_basis", "n", "terms")
    if not all(k in model for k in keys) or model["n"] != survey.n:
        return None
    return model


def refit_or_restore(
    ws: Path, history: list[dict], survey: Survey, target: str, terms: list[str], progress: bool
) -> SurveyModel:
    """The latest fit of `target` with `terms`, rebuilt from its saved hyperparameters when the workspace has
    them (no optimiser), else fitted anew."""
    for entry in reversed(history):
        if entry.get("target") != target or list(entry.get("terms", ())) != list(terms):
            continue
        try:
            sm = SurveyModel(survey, target, entry["terms"])
            model = saved_model(ws, entry, sm.survey)  # fitted on the rows the model uses now
            if model is None:
                break
            note(f"  from fit {entry['fit']}'s saved hyperparameters", progress)
            survey_fits(sm.survey).saved.update(_shared_entries(model.get("shared")))
            sm.fit(theta=np.asarray(model["theta"], float), n_basis=model["n_basis"])
            sm.calibration = Calibration.from_json(model.get("calibration"))
            return sm
        except WorkbenchError:
            break
    return SurveyModel(survey, target, terms).fit()


def calibrated(sm: SurveyModel) -> SurveyModel:
    """`sm` with the calibration of its predictive band (from blocked CV, unless it has one)."""
    if sm.calibration is None:
        sm.calibrate(make_folds(sm.survey, "blocked"))
    return sm


def _shared_entries(shared) -> dict[str, dict]:
    """The saved shared models' entries that have what a rebuild needs (a hand-edited file loses the rest:
    those models are fitted anew)."""
    if not isinstance(shared, dict):
        return {}
    return {
        k: v
        for k, v in shared.items()
        if isinstance(v, dict)
        and isinstance(v.get("theta"), list)
        and isinstance(v.get("n_basis"), dict)
    }


def latest_terms(history: list[dict], target: str) -> list[str]:
    """The terms of the history's latest fit of `target` (the paper's baseline if there is none)."""
    for h in reversed(history):
        if h["target"] == target:
            return h["terms"]
    return list(BASELINE)


def map_terms(survey: Survey, history: list[dict], target: str) -> list[str]:
    """The target's latest terms; a clock offset fitted for any aspect of the same vector (wind_dir, say)
    corrects the whole vector, so the map of its speed uses it too."""
    terms = latest_terms(history, target)
    vt = survey.vector_target(target)
    if vt is None or registry.corrections(terms, is_circular):
        return terms
    for h in reversed(history):
        other = survey.vector_target(h["target"])
        if other is not None and other.prefix == vt.prefix:
            offset = registry.corrections(h["terms"], is_circular)
            if offset:
                return terms + offset
    return terms


def save_residual_plots(table: Path, result: FitResult, fit_no: int) -> list[Path]:
    from forcemap.host.workbench.fits import plots
    ws = workspace_dir(table)
    m = result.model
    stem = f"fit-{fit_no:03d}-{m.target}"
    extra = {k: v for k, v in m.X.items() if np.ndim(v) == 1}  # position, a reference: not one column
    p1 = plots.save(
        plots.scatter_map(
            m.survey, result.cv.error, f"{m.target}: held-out residuals", "residual", "RdBu_r", True
        ),
        ws / f"{stem}-residual-map.png",
    )
    p2 = plots.save(
        plots.residual_panels(
            m.survey,
            result.cv.error,
            extra,
            f"{m.target}: held-out residual against covariates",
            m.target,
        ),
        ws / f"{stem}-residual-panels.png",
    )
    return [p1, p2]
