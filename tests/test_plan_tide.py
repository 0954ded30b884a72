"""`forcemap plan` in a tidal stream, against the simulator's truth: the plan that predicts the current the
tide will bring when the boat is on each line holds the lines better than the plan from the mean current.

A river whose own current (x 0.5: 0.5-1.25 m/s downstream) carries a tide (M2 1.6 m/s, S2 0.3 m/s) is
surveyed for 6 hours from 14:00 UTC. The mission is flown the next day from 23:18 UTC, in the strongest ebb
(the tide runs 1.7-1.8 m/s upstream: the water flows west where the survey's mean says east). Both plans
come from the survey's measurements; both missions are flown in the simulator's true river at that time,
with another seed, and scored on the intended lines with the true track.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.api import read_survey
from forcemap.host.plan.boat_model import BoatModel
from forcemap.host.plan.maps import survey_maps
from forcemap.host.plan.mission_io import read_mission, write_outputs
from forcemap.host.plan.planner import plan_mission
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.survey.reference import load_reference, with_reference
from forcemap.host.workbench.survey.table import load_survey

from bench.closed_loop import fly
from bench.tidal_survey import truth_survey

TIDE = ["tidal_stream:amplitude_m_s=1.6:s2_m_s=0.3:river=0.5"]
START_H = 33.3  # hours after the survey's start: the next night's ebb


def later_river(folder: Path, start: float) -> Path:
    """The river scenario starting at UNIX time `start` (the simulator's tide is the one of that time)."""
    text = (Path(sc.__file__).parent / "scenarios" / "river.toml").read_text()
    when = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(start))
    text = text.replace('start_utc = "2026-06-01T14:00:00Z"', f'start_utc = "{when}"')
    path = folder / "river_later.toml"
    path.write_text(text.replace('name = "river"', 'name = "river_later"'))
    return path


def plan_and_fly(  # type: ignore[no-untyped-def]
    table: Path,
    effect: str,
    start: float,
    scenario: Path,
    out: Path,
    stream: list[str] = TIDE,
    mission: str = "lawnmower",
    reference: tuple[Path, str] | None = None,
):
    """Fit the current with `effect` (on a `reference` current and station, if given, when there is an
    effect), plan the `mission` from `start`, fly it in the true river with `stream` then."""
    tb = out / f"{effect or 'mean'}.csv"
    shutil.copy(table, tb)
    use = reference if effect else None
    ref = {"reference_current": use[0], "reference_station": use[1]} if use else {}
    read_survey(tb, **ref).fit("current_speed", effects=effect, record=True)
    survey = load_survey(tb)
    if use:
        with_reference(survey, load_reference(*use))
    m = read_mission(mission, "river")
    frame = LocalFrame(survey.lat0, survey.lon0)
    wps, lines = frame.points_to_local(m.latlon), frame.points_to_local(m.lines_latlon)
    lo, hi = wps.min(axis=0) - 120.0, wps.max(axis=0) + 120.0
    maps = survey_maps(tb, survey, (lo[0], hi[0], lo[1], hi[1]), False, start, 3 * 3600.0)
    result = plan_mission(wps, m.speeds, lines, maps, BoatModel())
    p = result.planned
    path = write_outputs(out / f"planned-{effect or 'mean'}", frame.points_to_latlon(p.plan.wps),
                         p.plan.speeds, frame.points_to_latlon(p.plan.lines), p.to_json(), effect)[0]  # fmt: skip
    return maps, fly(path, str(scenario), 5, stream, 1.5 * p.track.duration + 120)


@pytest.mark.slow
def test_the_tidal_plan_beats_the_plan_from_the_mean_current(tmp_path: Path) -> None:
    table = truth_survey("river", TIDE, 3, 6 * 3600.0, tmp_path / "survey")
    start = sc.load("river").t0 + START_H * 3600
    scenario = later_river(tmp_path, start)
    mean_maps, mean = plan_and_fly(table, "", start, scenario, tmp_path)
    tide_maps, tide = plan_and_fly(table, "tide", start, scenario, tmp_path)
    # the mean current's map does not change in time; the tide's is gridded along the mission from its start
    assert mean_maps.current.times is None
    assert tide_maps.current.times is not None and tide_maps.current.times[0] == start
    assert any("when the boat is on it" in n for n in tide_maps.notes)
    # the map at the start says the water runs upstream (west), as the simulator's does then
    e, _, _ = tide_maps.current.sample(np.array([[0.0, 0.0]]), start)
    assert e[0] < -0.3
    # flown in the true river: p95 distance from the lines, worst line, at most half the mean plan's
    assert tide.summary["p95_worst_line"] <= 0.6 * mean.summary["p95_worst_line"], (
        tide.summary,
        mean.summary,
    )
    assert tide.summary["coverage"] >= 0.95


@pytest.mark.parametrize("t", [None, 50.0])
def test_a_field_in_time_is_linear_between_its_slices(t: float | None) -> None:
    from forcemap.host.plan.maps import Field, Maps
    from forcemap.host.plan.predict import predict_track

    z = np.zeros((3, 4, 4))
    east = z + np.array([1.0, -1.0, -1.0])[:, None, None]  # east at 0 s, west from 100 s on
    f = Field(0.0, 0.0, 50.0, east, z, z, z, times=np.array([0.0, 100.0, 200.0]))
    assert f.at(10.0, 10.0, t=25.0) == (0.5, 0.0) and f.at(10.0, 10.0, t=-5.0) == (1.0, 0.0)
    assert f.at(10.0, 10.0, t=500.0) == (-1.0, 0.0)  # held at the last slice
    assert f.sample(np.zeros((1, 2)), 90.0)[0][0] == -1.0  # the nearest slice
    # a boat drifting in it from t: the track reads the current at each step's time
    maps = Maps(f, Field.still(), 0.0, 0.0, start=t)
    wps = np.array([[0.0, 0.0], [0.0, 150.0]])
    tr = predict_track(
        wps, None, maps, __import__("forcemap.host.plan.boat_model", fromlist=["x"]).BoatModel()
    )
    drift = float(np.mean(tr.x))
    assert (drift < 0) if t is not None else (drift > 0)  # from 50 s the water runs west
