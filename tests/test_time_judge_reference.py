"""A reference station's prediction judged as a form of change in time (timejudge/reference_form.py), on a
lapped track with a known truth (tests/test_time_judge.py's laps, six hours of them).

A current that follows the station at a ratio and a time offset is named as the station's tide, with its
ratio and offset; noise alone is not; and a seiche that the station does not predict is still named a
period.
"""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.vessel.reference_current import ReferenceCurrent, Station
from forcemap.host.workbench.diagnose.catalogue import time_form_cause
from forcemap.host.workbench.timejudge.judge import judge_time
from forcemap.host.workbench.timejudge.reference_form import ReferenceForm
from forcemap.host.workbench.timejudge.revisits import revisit_pairs, stretch_length

from tests.test_time_judge import THRESHOLD, lap_track, noise

SPAN_S = 6 * 3600.0
UTC0 = 1400284800.0  # 2014-05-17 00:00 UTC
STATION = Station(
    id="T1",
    name="a test station",
    lat=37.8,
    lon=-122.4,
    flood_dir=90.0,
    constituents=("M2", "K1"),
    amplitude=np.array([0.8, 0.3]),
    phase_deg=np.array([40.0, 200.0]),
)
REFERENCE = ReferenceCurrent({"T1": STATION}, "test")


@pytest.fixture(scope="module")
def track():  # type: ignore[no-untyped-def]
    return lap_track(SPAN_S)


def judged(values: np.ndarray, t, xy, heading):  # type: ignore[no-untyped-def]
    """The revisits' verdict on `values` with the station's prediction as a form."""
    rp = revisit_pairs(xy, t, 20.0, stretch_length(t, values - np.median(values)))
    form = ReferenceForm(REFERENCE, np.full(len(t), 37.8), np.full(len(t), -122.4), UTC0, rp)
    d = values[rp.pairs[:, 1]] - values[rp.pairs[:, 0]]
    return judge_time(d, rp, xy, heading, permutations=299, reference=form)


def test_a_current_that_follows_the_station_is_named_with_its_ratio_and_offset(track):
    t, xy, heading = track
    ratio, offset = 0.6, 1200.0
    values = noise(len(t), 3) + ratio * STATION.speed(UTC0 + t - offset)
    v = judged(values, t, xy, heading)
    assert v.p_value <= THRESHOLD + 1e-12, v
    assert v.best.name == "reference", v.best
    assert v.station == "T1"
    assert abs(v.ratio - ratio) <= 0.1 * ratio, v.ratio
    assert abs(v.offset_s - offset) <= 600.0, v.offset_s
    cause = time_form_cause(v, "current", short_for_tide=False)
    assert "as the reference station predicts it (station T1" in cause, cause


def test_noise_alone_is_not_the_stations_tide(track):
    t, xy, heading = track
    v = judged(noise(len(t), 4), t, xy, heading)
    reference = next(f for f in v.forms if f.name == "reference")
    assert reference.p_value > 0.05 and v.best.name != "reference", (v.best, reference)


def test_a_seiche_the_station_does_not_predict_is_named_a_period(track):
    t, xy, heading = track
    period = 4440.0
    values = noise(len(t), 5) + 0.15 * np.sin(2 * np.pi * t / period)
    v = judged(values, t, xy, heading)
    assert v.p_value <= THRESHOLD + 1e-12, v
    assert v.best.name == "periodic", v.best
    assert abs(v.best.period_s - period) <= 2 * v.period_sd_s, (v.best, v.period_sd_s)
