"""Diagnose with a reference current (issue 60, item 4): on both shared San Francisco Bay days, with NOAA's
central-bay stations given, the change in time the revisits find is named as the stations' tide, and the
term advised is the map of each place's ratio and offset to its station (`tide(reference, position)`).

Without a reference the same revisits name a period of the ladder (a 3.5-h "seiche" on the 7.4-h flood of
2014-05-17, tests/test_time_judge_real.py); a prediction given beforehand that alone carries the evidence for
time is the cause to name, and what it does not predict is left for the next round.
"""

from __future__ import annotations

import pytest
from forcemap.host.workbench.diagnose.rounds import diagnose
from forcemap.host.workbench.survey.reference import load_reference, with_reference
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms.spec import BASELINE
from forcemap.host.workbench.timejudge.candidate import REFERENCE_TERM, time_term, time_verdict

from tests.test_reference_tide import NOAA as STATIONS
from tests.test_sfbay_real import SFBAY

DUXBURY = "nmea/sfbay/duxbury.nmea.gz"
# diagnose's threshold on a round of about twenty candidates (0.05 over them)
THRESHOLD = 0.05 / 20


def referenced(real_case, log: str):  # type: ignore[no-untyped-def]
    """The log's exported table with the stations as its reference current."""
    return with_reference(load_survey(real_case(log).csv), load_reference(STATIONS))


@pytest.mark.parametrize("log", [SFBAY, DUXBURY])
def test_the_revisits_name_the_stations_tide(real_case, log):
    sm = SurveyModel(referenced(real_case, log), "current_speed", list(BASELINE)).fit()
    found = time_verdict(sm, threshold=THRESHOLD)
    assert found is not None
    v = found[0]
    assert v.p_value <= THRESHOLD, v.p_value
    assert v.best.name == "reference" and v.station, v.best
    reference = next(f for f in v.forms if f.name == "reference")
    assert reference.p_value <= v.p_value, reference
    assert time_term(v, "current_speed") == REFERENCE_TERM
    # what the map leaves follows the station with the flood's sign: a positive ratio, a change of the
    # size the revisits fit
    assert v.ratio > 0 and v.change > 2 * v.change_sd, (v.ratio, v.change, v.change_sd)


def test_diagnose_names_the_tide_and_not_the_currents_direction(real_case):
    d = diagnose(referenced(real_case, SFBAY), "current_speed", rounds=1, progress=False)
    first = d.rounds[0].added
    assert first is not None and first.covariate == "t", d.summary()
    assert first.term == REFERENCE_TERM, first.term
    assert "as the reference station predicts it" in d.summary()
    credited = [c.covariate for c in d.candidates if c.significant]
    assert "current_dir" not in credited and "heading_rel_current" not in credited, credited
