"""The axis a tide is modelled along, chosen by each real log (host/workbench/targets/axis_choice.py, issue 36).

A speed or direction with a tide is split along and across the oscillation's axis. On a yacht's log the
place's "mean current" is mostly leeway and speed-log error, which follow the legs: an axis at each place
then follows that error, and a uniform tide projected on it changes amplitude from place to place. Where a
real stream turns with its channels, the axis at each place is right. Two real logs, one of each:

- the Flensburg race with a uniform M2 stream injected along 050 deg (tests/real_cases.py, ``fjord_tide``):
  one axis for the survey must be chosen, and it must lie along the injected stream;
- the race through San Francisco Bay's real flood (tests/test_sfbay_real.py), which sets along the City
  Front and turns with the channels: the axis at each place must be kept.
"""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.survey_fits import frame_direction
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms import time_terms
from forcemap.host.workbench.terms.spec import BASELINE

from bench.inject_cases import INJECTED
from tests.test_sfbay_real import SFBAY

pytestmark = pytest.mark.slow


def tide_model(real_case, name: str) -> SurveyModel:  # type: ignore[no-untyped-def]
    """`fit --target current_speed --effects tide` on a real case, as the workbench fits it."""
    survey = load_survey(real_case(name).csv)
    return SurveyModel(survey, "current_speed", [*BASELINE, "tide"]).fit()


def axial_gap_deg(a: np.ndarray, b: float) -> np.ndarray:
    """Angle between axes (0-90 deg: an axis and its reverse are one axis)."""
    return np.abs((np.asarray(a) - b + 90.0) % 180.0 - 90.0)


def test_a_uniform_tide_on_a_yachts_log_is_modelled_along_one_axis_its_own(real_case):
    sm = tide_model(real_case, "fjord_tide")
    a = sm.axis
    assert a is not None and a.one_axis, a
    assert a.rmse_survey < a.rmse_place and a.samples == sm.survey.n
    angle = np.degrees(np.arctan2(sm.ue, sm.un))
    assert np.ptp(angle) < 1e-6  # one axis at every row
    injected = INJECTED["fjord_tide"].effect.current.toward_deg
    assert axial_gap_deg(angle[0], injected) < 15.0, (angle[0], injected)
    # maps are drawn in the same frame
    xy = sm.survey.xy[:: max(1, sm.survey.n // 200)]
    ue, un = frame_direction(sm.survey, sm.vector, xy, None, sm.frame_terms)
    assert np.allclose(ue, sm.ue[0]) and np.allclose(un, sm.un[0])
    # and `fit` says which, with the numbers that chose it
    assert any(line.strip() == a.line() for line in time_terms.describe(sm))
    assert time_terms.tide_summary(sm)["axis"]["one_axis"] is True


def test_a_flood_that_turns_with_the_channels_keeps_the_axis_at_each_place(real_case):
    sm = tide_model(real_case, SFBAY)
    a = sm.axis
    assert a is not None and not a.one_axis, a
    assert a.rmse_place < a.rmse_survey
    angle = np.degrees(np.arctan2(sm.ue, sm.un))
    # the axis turns over the bay: not one direction
    assert np.ptp(axial_gap_deg(angle, float(np.median(angle)))) > 20.0
