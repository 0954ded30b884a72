"""Diagnose on real logs with a known change in time put into their NMEA (tests/real_cases.py, issue 36).

Each case is a real race with everything as recorded (speed log, compass, wind, their noise, faults and
latencies) plus a known current: a tidal stream in the Flensburg fjord, a 74-minute seiche on Lake Geneva.
Diagnose must find time where the boat comes back, say how many revisit pairs judged it, and the advised
term must cut the error where the boat comes back. The clean logs gain no time term their revisits do
not support: whenever `t` is credited, its revisit p-value is the one that passed.
"""

from __future__ import annotations

import pytest
from forcemap.host.workbench.diagnose import diagnose
from forcemap.host.workbench.fitting import fit_target
from forcemap.host.workbench.spec import BASELINE
from forcemap.host.workbench.table import load_survey

from bench.inject_cases import FJORD

pytestmark = pytest.mark.slow


def time_findings(d) -> list:  # type: ignore[no-untyped-def]
    """Every round's credited `t`."""
    return [r.added for r in d.rounds if r.added is not None and r.added.covariate == "t"]


def threshold(r) -> float:  # type: ignore[no-untyped-def]
    """The round's significance: 0.05 over its candidates (Bonferroni)."""
    return 0.05 / len(r.candidates)


@pytest.fixture(scope="module")
def fjord_tide(real_case):  # type: ignore[no-untyped-def]
    built = real_case("fjord_tide")
    survey = load_survey(built.csv)
    return survey, diagnose(survey, "current_speed", progress=False)


def test_the_fjords_tidal_stream_is_found_where_the_boat_comes_back(fjord_tide):
    _, d = fjord_tide
    [found] = time_findings(d)
    v = found.time
    assert v is not None, "judged at the revisits"
    assert v.pairs >= 50 and v.crossings >= 5
    assert found.p_value == v.p_value <= 0.05 / 20
    assert v.share > 0.05
    # what the finding says: the pairs, and what they showed
    assert f"{v.pairs} revisit pairs" in found.note
    assert "tide" in d.summary()


def test_the_tide_term_cuts_the_error_where_the_boat_comes_back(fjord_tide):
    """`fit --effects tide` against the baseline: the crossline RMSE (each time stretch held out, scored
    where another pass comes back) falls."""
    survey, _ = fjord_tide
    base = fit_target(survey, "current_speed", list(BASELINE), progress=False)
    tide = fit_target(survey, "current_speed", [*BASELINE, "tide"], progress=False)
    assert base.crossline is not None and tide.crossline is not None
    assert tide.crossline["crossline_rmse"] < 0.97 * base.crossline["crossline_rmse"], (
        base.crossline,
        tide.crossline,
    )


def test_the_lakes_seiche_is_found_where_the_boat_comes_back(real_case):
    d = diagnose(load_survey(real_case("geneva_seiche").csv), "current_speed", progress=False)
    found = time_findings(d)
    assert found, d.summary()
    v = found[0].time
    assert v is not None and v.p_value <= 0.05 / 20
    assert v.best.name in ("periodic", "drift"), v.best


@pytest.mark.parametrize("name", [FJORD])
def test_a_clean_log_gains_no_time_term_its_revisits_do_not_support(real_case, name):
    d = diagnose(load_survey(real_case(name).csv), "current_speed", progress=False)
    for r in d.rounds:
        t = next((c for c in r.candidates if c.covariate == "t"), None)
        if t is None or t.time is None:
            continue
        # credited only on the revisits' own evidence, never on a blocked gain their p-value contradicts
        assert t.significant == (t.time.p_value <= threshold(r)) or (
            t.significant and t.blocked_p is not None and t.blocked_p <= threshold(r)
        )
