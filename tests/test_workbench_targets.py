"""Survey models without side effects: construction does not fit, derived covariates do not become columns,
shared fits are explicit, and figures leave matplotlib's process-wide state alone."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.survey_fits import derived_column, survey_fits
from forcemap.host.workbench.targets.target_model import SurveyModel

from bench.synth_survey import make_survey


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    return make_survey("river", [], 2, 600.0, tmp_path_factory.mktemp("survey"))


def test_construction_validates_but_does_not_fit(table):
    survey = load_survey(table)
    sm = SurveyModel(survey, "current_speed", ["const", "gp(position, matern32)", "depth"])
    assert not hasattr(sm, "primary") and not hasattr(sm, "X")
    assert not survey_fits(survey).shared_hypers()  # the flow frame is fitted by fit(), not before
    sm.fit()
    frames = [k for k in survey_fits(survey).shared_hypers() if k.startswith("frame/")]
    assert len(frames) == 2  # one flow frame: its east and north models
    again = SurveyModel(survey, "current_speed").fit()
    assert again.secondary is sm.secondary  # one secondary component per survey
    with pytest.raises(WorkbenchError, match="unknown target"):
        SurveyModel(survey, "no_such_column")


def test_a_current_or_wind_a_log_cannot_have_says_what_it_lacked(table, tmp_path):
    """A log without a heading has no current and no wind over ground: asking for one says so (the
    heading it lacked), not just that the name is unknown; a name of no family stays unknown."""
    import pandas as pd

    df = pd.read_csv(table)
    gone = [c for c in df.columns if c.startswith(("current_", "wind_")) or c == "heading"]
    df.drop(columns=gone).to_csv(tmp_path / "no_heading.csv", index=False)
    survey = load_survey(tmp_path / "no_heading.csv")
    for target, family in (("current_speed", "current"), ("wind_dir", "wind")):
        with pytest.raises(WorkbenchError) as e:
            SurveyModel(survey, target)
        said = str(e.value)
        assert said.startswith(f"no '{target}' in this table: a {family} needs the boat's heading")
        assert "which this log lacks; try one of:" in said, said
    with pytest.raises(WorkbenchError, match="unknown target 'salinity'"):
        SurveyModel(survey, "salinity")


def test_derived_covariates_are_not_added_to_the_table(table):
    survey = load_survey(table)
    before = list(survey.columns)
    stw = derived_column(survey, "stw")
    assert list(survey.columns) == before and "stw" not in survey.numeric_columns()
    c = survey.columns
    ground = np.column_stack(
        [c["sog"] * np.sin(np.radians(c["cog"])), c["sog"] * np.cos(np.radians(c["cog"]))]
    )
    water = ground - np.column_stack([c["current_east"], c["current_north"]])
    assert np.allclose(stw, np.linalg.norm(water, axis=1))
    # the synthetic boat holds 3.5 m/s through the water; the measured current is noisy
    assert abs(float(np.median(stw)) - 3.5) < 0.1
    assert derived_column(survey, "stw") is stw  # computed once per survey
    rel = derived_column(survey, "heading_rel_current")
    assert list(survey.columns) == before and np.all(np.abs(rel) <= 180.0)


def test_figures_leave_the_backend_and_pyplot_alone(table):
    code = f"""
import sys, matplotlib
from forcemap.host.workbench.fits import plots
from forcemap.host.workbench.survey.table import load_survey
s = load_survey({str(table)!r})
png = plots.png_bytes(plots.scatter_map(s, s.columns["depth"], "depth", "m"))
assert png[:8] == b"\\x89PNG\\r\\n\\x1a\\n", png[:8]
assert "matplotlib.pyplot" not in sys.modules
print(matplotlib.get_backend())
"""
    env = {"MPLBACKEND": "svg", "PATH": "/usr/bin:/bin"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=False
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "svg"


def test_a_vectors_components_share_one_gram_and_cv_reuses_the_fit_pass(table):
    """East and north frame components (same features, same inputs) share one design through the survey's
    DesignCache, so one Gram matrix; with the folds planned, their fold Grams come from the fit's pass and
    the held-out predictions equal those of a design that computes its fold Grams afresh."""
    import copy

    from forcemap.host.workbench.fits.fit import make_folds

    survey = load_survey(table)
    folds = make_folds(survey, "blocked")
    survey_fits(survey).grams.plan = folds
    sm = SurveyModel(survey, "current_speed").fit()
    me, mn = survey_fits(survey).frame(sm.vector)
    assert me.design_ is mn.design_ and me.design_.fast is not None
    assert sm.primary.design_ is sm.secondary.design_  # along and across: the same basis here
    assert sm.primary.fold_residuals_  # Phi_f'r_f of every fold, from the fit's pass
    # the same model on a copy of its design that has no fold Grams: they are computed afresh by the CV
    fresh = copy.copy(me)
    fresh.design_ = copy.copy(me.design_)
    fresh.design_._folds, fresh.design_._fold_ids, fresh.fold_residuals_ = {}, {}, {}
    for a, b in zip(me.cv_predict(folds), fresh.cv_predict(folds), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("target", ["current_speed", "current_dir", "wind_dir"])
def test_a_mean_without_spread_is_the_mean_of_its_draws(table, target):
    """With no latent spread (the diagnosis' CV: `interval=False`), a speed's or a direction's mean is
    computed without the draws; it equals the mean over the draws (`spread=True` takes that path)."""
    sm = SurveyModel(load_survey(table), target).fit()
    mu_p, mu_s = sm.primary.predict(sm.X), sm.secondary.predict(sm.X)
    zero = np.zeros_like(mu_p)
    args = (mu_p, zero, sm.primary.noise_std_, mu_s, zero, sm.secondary.noise_std_)
    mean, lo, hi = sm.combine(*args, interval=False)
    drawn = sm.combine(*args, interval=False, spread=True)[0]
    assert np.isnan(lo).all() and np.isnan(hi).all()
    if target.endswith("_dir"):
        np.testing.assert_allclose((mean - drawn + 180.0) % 360.0 - 180.0, 0.0, atol=1e-9)
    else:
        np.testing.assert_allclose(mean, drawn, rtol=1e-12)
    # with a spread the draws are taken, and a speed's mean grows (|v| is convex)
    if target == "current_speed":
        spread = sm.combine(mu_p, zero + 0.1, 0.0, mu_s, zero + 0.1, 0.0, interval=False)[0]
        assert (spread >= mean - 1e-12).all() and spread.mean() > mean.mean()
