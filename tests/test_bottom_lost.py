"""The bottom lost (issue 28): where soundings scatter more than a seabed can, the stretch is flagged, listed
with its times and kept out of the depth map; false echoes over a bottom that is still there are not."""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
import pytest
from forcemap.host.workbench.engine.model import small_blas
from forcemap.host.workbench.fits.fit import fit_target
from forcemap.host.workbench.survey.spikes import LOST_WHY, find_spikes
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.terms.spec import BASELINE
from forcemap.sim_devices.offline import make_survey


@dataclass
class Track:
    """What find_spikes reads of a survey: one sounding a second."""

    trel: np.ndarray
    keep_outliers: bool = False
    cache: dict = field(default_factory=dict)


def _spikes(depth: np.ndarray):
    return find_spikes(Track(np.arange(len(depth), dtype=float)), "depth", [depth], "depth")


def _bottom(n: int, rng) -> np.ndarray:
    """A seabed at 70-105 m, changing slowly along the track, with a sounder's noise."""
    return 87.5 + 17.5 * np.sin(np.linspace(0, 3, n)) + 0.05 * rng.standard_normal(n)


def test_returns_scattering_from_3_to_70_m_are_the_bottom_lost():
    rng = np.random.default_rng(5)
    depth = _bottom(1200, rng)
    depth[400:640] = rng.uniform(3.0, 70.0, 240)  # four minutes without the bottom
    sp = _spikes(depth)
    assert [(s.i0, s.i1) for s in sp.stretches] == [(400, 639)]
    assert np.array_equal(np.flatnonzero(sp.lost), np.arange(400, 640))
    assert np.array_equal(np.flatnonzero(sp.flagged), np.arange(400, 640))
    (line,) = sp.lines()
    assert LOST_WHY in line and "6.7-10.7 min" in line and "240 soundings" in line


@pytest.mark.parametrize("rate", [0.1, 0.6])
def test_false_echoes_over_a_bottom_that_is_there_are_not(rate):
    """Six soundings in ten false (3-20 m), for the whole track: the bottom is under the rest."""
    rng = np.random.default_rng(6)
    depth = _bottom(1200, rng)
    echo = rng.random(1200) < rate
    depth[echo] = rng.uniform(3.0, 20.0, echo.sum())
    sp = _spikes(depth)
    assert not sp.stretches and sp.lost is None
    assert np.array_equal(sp.flagged, echo)


def _fit(path, keep_outliers=False):
    """The depth map as `forcemap fit TABLE --target depth` makes it (baseline terms, blocked CV)."""
    survey = load_survey(path, keep_outliers=keep_outliers)
    with small_blas():
        return fit_target(survey, "depth", list(BASELINE), progress=False), survey


def test_the_simulators_sounder_losing_the_bottom_for_four_minutes(tmp_path):
    """The deep basin (70-100 m), the sounder's returns scattering from 3 to 70 m for four minutes of a
    15-minute survey: the stretch is found at the fault's times, and the depth map's blocked-CV RMSE
    is the clean run's, where with the stretch kept in (--keep-outliers) it is many times that."""
    at, dur = 300.0, 240.0
    faults = f"bottom_lost:at={at}:for={dur}"
    lost = make_survey("deep", [], 1, 900.0, tmp_path / "l", faults=faults)
    clean = make_survey("deep", [], 1, 900.0, tmp_path / "c")
    res, survey = _fit(lost)
    ref, _ = _fit(clean)
    spikes = res.model.spikes
    (stretch,) = spikes.stretches
    truth = json.loads((tmp_path / "l" / "truth" / "effects.json").read_text())
    t_start = truth["t0"] + at
    # its ends within 3 soundings of the fault's: two returns of the scatter may agree by chance
    assert abs(survey.t0 + stretch.t0 - t_start) <= 3.0
    assert abs(survey.t0 + stretch.t1 + 1.0 - (t_start + dur)) <= 3.0
    assert stretch.n >= truth["instruments"]["bottom_lost_soundings"] - 6
    assert res.cv.rmse < 1.25 * ref.cv.rmse, (res.cv.rmse, ref.cv.rmse)
    kept, _ = _fit(lost, keep_outliers=True)
    assert kept.cv.rmse > 4.0 * ref.cv.rmse, (kept.cv.rmse, ref.cv.rmse)
