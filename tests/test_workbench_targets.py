"""Survey models without side effects: construction does not fit, derived covariates do not become columns,
shared fits are explicit, and figures leave matplotlib's process-wide state alone."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey_fits import derived_column, survey_fits
from forcemap.host.workbench.table import load_survey
from forcemap.host.workbench.targets import SurveyModel

from bench.synth_survey import make_survey


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    return make_survey("river", [], 2, 600.0, tmp_path_factory.mktemp("survey"))


def test_construction_validates_but_does_not_fit(table):
    survey = load_survey(table)
    sm = SurveyModel(survey, "current_speed", ["const", "gp(position, matern32)", "depth"])
    assert not hasattr(sm, "primary") and not hasattr(sm, "X")
    assert not survey_fits(survey)._frames  # the flow frame is fitted by fit(), not before
    sm.fit()
    assert len(survey_fits(survey)._frames) == 1
    again = SurveyModel(survey, "current_speed").fit()
    assert again.secondary is sm.secondary  # one secondary component per survey
    with pytest.raises(WorkbenchError, match="unknown target"):
        SurveyModel(survey, "no_such_column")


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
from forcemap.host.workbench import plots
from forcemap.host.workbench.table import load_survey
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
