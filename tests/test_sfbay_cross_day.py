"""Fit one San Francisco Bay day, predict the other, both ways (issue 60; bench/bench_reference_current.py).

tests/data/real/nmea/sfbay holds two days of one racing yacht (2014-05-17, a spring flood on the City Front;
2014-05-10, a neap on a wider course), tests/data/real/tides NOAA's constants of the 12 central-bay current
stations. `fit --effects tide --reference-current` on one day predicts the other, scored on 15-minute means
while under way: its vector RMSE no worse than the prediction of the station nearest each bin's median
position, at most 0.8 times that of the training day's mean current, and below the station's on the bins
within 500 m of the training day's track.
"""

from __future__ import annotations

import pytest
from forcemap.host.workbench.survey.reference import load_reference

from bench.bench_reference_current import DAYS, REFERENCE, direction

pytestmark = pytest.mark.slow


@pytest.mark.parametrize(("train", "test"), [("05-17", "05-10"), ("05-10", "05-17")])
def test_a_day_predicts_the_other_better_than_its_stations(real_case, train, test) -> None:
    tables = {day: real_case(name).csv for day, name in DAYS.items()}
    r = direction(train, test, tables, ["const", "gp(position, matern32)", "tide"], load_reference(REFERENCE))
    assert r["terms"][-1] == "tide(reference, position)"
    assert r["model"] <= r["station"], r
    assert r["model"] <= 0.8 * r["mean"], r
    assert r["near_bins"] >= 5 and r["model_near"] < r["station_near"], r
