"""Soundings on the simulator, where the truth is known (issue 37).

- A sounder that loses the bottom beyond its range in a rough sea: the strait (70 m at its sides, 108 m
  along its middle) under the lawnmower along it, the sounder's range 103 m, so it loses the bottom
  over the middle line, about a fifth of the survey. The stretches are found within 30 s of
  their true ends, and the depth map's blocked-CV RMSE is that of the same survey with the bottom held
  within 20 %.
- A hull that heels with the wind (up to 25 deg, a 10 deg beam) on a windy lake, main lines along the
  wind and cross lines across it: the heading relative to the wind decides the heel. Corrected for the
  hull's attitude, the soundings agree at the crossings within 20 % of an upright survey's; diagnose no
  longer credits the heading, and without the attitude it names heel. The import's estimator finds
  the beam angle from the crossings.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.convert.depth_findings import tilt_finding
from forcemap.host.convert.export import export
from forcemap.host.fuse.calibration import Calibration
from forcemap.host.workbench.depth.water_level import crossline_rmse
from forcemap.host.workbench.diagnose.catalogue import TILT
from forcemap.host.workbench.diagnose.rounds import diagnose
from forcemap.host.workbench.engine.model import small_blas
from forcemap.host.workbench.fits.fit import fit_target
from forcemap.host.workbench.survey.spikes import target_spikes
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.terms.spec import BASELINE
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.offline import run_to_mcap

from tests.cache import shared_dir
from tests.sim_surveys import simulated

STRAIT_S = 720.0
RANGE_M = 103.0
HEEL_S = 600.0
BEAM = 10.0
CROSSLINES = """[mission]
description = "main lines east-west (along the wind), cross lines north-south (across it)"
kind = "waypoints"
points = [[-35.0, -30.0], [35.0, -30.0], [35.0, -10.0], [-35.0, -10.0], [-35.0, 10.0], [35.0, 10.0],
          [35.0, 30.0], [-35.0, 30.0], [-30.0, 35.0], [-30.0, -35.0], [-10.0, -35.0], [-10.0, 35.0],
          [10.0, 35.0], [10.0, -35.0], [30.0, -35.0], [30.0, 35.0]]
loop = true
"""


def _fit(table: Path):
    survey = load_survey(table)
    with small_blas():
        return fit_target(survey, "depth", list(BASELINE), progress=False), survey


@pytest.fixture(scope="module")
def strait(tmp_path_factory):
    """Made once per run (tests/sim_surveys.py), whichever worker runs a test of it first."""
    lost = simulated(
        tmp_path_factory, "strait", [], 1, STRAIT_S, faults=f"beyond_range:range={RANGE_M}"
    )
    held = simulated(tmp_path_factory, "strait", [], 1, STRAIT_S)
    truth = json.loads((lost.parent / "truth" / "effects.json").read_text())
    return lost, held, truth


@pytest.mark.slow
def test_the_bottom_lost_beyond_the_sounders_range_is_found_and_left_out(strait):
    lost, held, truth = strait
    res, survey = _fit(lost)
    ref, _ = _fit(held)
    inst = truth["instruments"]
    assert 0.15 <= inst["bottom_lost_soundings"] / STRAIT_S <= 0.25  # about a fifth of the survey
    # the true stretches, those the survey saw (after its first fix), each found within 30 s
    true = [(a, b) for a, b in inst["bottom_lost_stretches"] if b - a >= 30.0]
    found = [
        (survey.t0 + s.t0 - truth["t0"], survey.t0 + s.t1 - truth["t0"])
        for s in res.model.spikes.stretches
    ]
    assert true and len(found) == len(true), (true, found)
    for (a, b), (fa, fb) in zip(true, found, strict=True):
        assert abs(fa - a) <= 30.0 and abs(fb - b) <= 30.0, (true, found)
    assert res.cv.rmse <= 1.2 * ref.cv.rmse, (res.cv.rmse, ref.cv.rmse)


def _heel_survey(
    d: Path, scenario: Path, mission: Path, effects: list[str], beam: float | None
) -> Path:
    sim = Simulation(
        scenario=str(scenario), mission=str(mission), effects=effects, seed=1, truth_dir=d / "truth"
    )
    paths = run_to_mcap(sim, HEEL_S, d / "logs", seed=1, boat=Calibration(sounder_beam_deg=beam))
    export(paths, "csv", str(d / "samples.csv"))
    return d / "samples.csv"


def _heel_surveys(d: Path) -> None:
    from forcemap.host.vessel import scenario as sc

    lake = Path(sc.load("lake").path).read_text()
    assert "\nspeed = 2.5" in lake
    scenario = d / "windy_lake.toml"  # the lake's breeze, at 6 m/s: a beam reach heels the hull
    scenario.write_text(
        lake.replace("\nspeed = 2.5", "\nspeed = 6.0").replace(
            'name = "lake"', 'name = "windy_lake"'
        )
    )
    mission = d / "crosslines.toml"
    mission.write_text(CROSSLINES)
    for name, effects, beam in (
        ("upright", [], None),
        ("heeled", ["heel"], None),
        ("corrected", ["heel"], BEAM),
    ):
        _heel_survey(d / name, scenario, mission, effects, beam)


@pytest.fixture(scope="module")
def heel(tmp_path_factory):
    """The three heel surveys, made once per run (tests/cache.py) and only read by the tests."""
    key = f"soundings-heel-windy_lake-crosslines-{HEEL_S:g}-beam{BEAM:g}"
    d = shared_dir(tmp_path_factory, key, _heel_surveys)
    return {name: d / name / "samples.csv" for name in ("upright", "heeled", "corrected")}


def _crossline(table: Path) -> float:
    res, _ = _fit(table)
    return crossline_rmse(res.model)["crossline_rmse"]


@pytest.mark.slow
def test_the_attitude_correction_makes_the_crossings_agree_as_an_upright_hulls(heel):
    upright = load_survey(heel["upright"])
    heeled = load_survey(heel["corrected"])
    assert np.nanpercentile(np.abs(upright.columns["roll"]), 95) < 3.0
    assert (
        18.0 < np.nanpercentile(np.abs(heeled.columns["roll"]), 99) < 27.0
    )  # up to 25 deg and noise
    ref, raw, fixed = (_crossline(heel[k]) for k in ("upright", "heeled", "corrected"))
    assert raw > 1.3 * ref, (raw, ref)  # the heel is there: the legs across the wind read long
    assert fixed <= 1.2 * ref, (fixed, ref)


@pytest.mark.slow
def test_the_beam_angle_is_estimated_from_the_crossings(heel):
    survey = load_survey(heel["heeled"])
    c = {k: survey.columns[k] for k in ("t", "lat", "lon", "depth", "roll", "pitch")}
    f, beam = tilt_finding(c, "depth", Calibration())
    assert beam is not None and abs(beam - BEAM) <= 3.0, f.message
    assert f.applied and float(f.extra["after_m"]) < 0.8 * float(f.extra["before_m"])


@pytest.mark.slow
def test_diagnose_credits_the_heading_to_heel_and_not_once_corrected(heel):
    raw = load_survey(heel["heeled"])
    for c in ("roll", "pitch"):  # a log with no attitude
        raw.columns.pop(c)
    with small_blas():
        d = diagnose(raw, "depth", rounds=1, progress=False)
        fixed = diagnose(load_survey(heel["corrected"]), "depth", rounds=1, progress=False)
    best = d.rounds[0].added
    assert best is not None and re.search(TILT, best.covariate), d.summary()
    assert "heel" in best.explanation and "misaligned or shadowed" not in best.explanation
    added = fixed.rounds[0].added
    assert added is None or not re.search(TILT, added.covariate), fixed.summary()
    credited = [
        c.covariate
        for c in fixed.rounds[0].candidates
        if c.significant and re.search(TILT, c.covariate)
    ]
    assert not credited, fixed.summary()


@pytest.mark.slow
def test_the_spike_test_keeps_the_bottom_held(strait):
    """The same strait with the bottom held: nothing is lost."""
    _, held, _ = strait
    assert not target_spikes(load_survey(held), "depth").stretches
