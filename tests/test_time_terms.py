"""Time terms that predict, on the simulator with a known truth (issue 36, item 3).

The surveys are the simulator's true track with the pipeline's measured noise (bench/tidal_survey.py: a day
through the whole pipeline at 4 Hz would be 12 minutes of CPU): a lake with a tidal stream (4 hours), a lake
with a seiche (3.5 hours), and a river with a reversing tide over a day. What must hold: the tide's
amplitude and Greenwich phase come back with an sd that covers the truth; a fit of the first 60 % of the
day predicts the last 40 % within 1.5 times its in-sample error and a GP in time does not; the seiche's
period comes back within its sd; `--at` predicts the current the simulator has at that time, on `fit`,
`grid` and the API; and a bad `--at` is one line and exit 2.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.api import read_survey
from forcemap.host.cli import main
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.survey.at_time import parse_at
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms.tide import constituents
from forcemap.sim_devices import effects as fx
from forcemap.sim_devices.fields import World

from bench.tidal_survey import truth_survey

pytestmark = pytest.mark.slow
LAKE_TIDE = ["tidal_stream:amplitude_m_s=0.5:phase_deg=200"]
RIVER_TIDE = ["tidal_stream:amplitude_m_s=1.0:s2_m_s=0.25:river=0.5"]
TOMORROW = "2026-06-02T14:00Z"  # a day after the simulator's surveys start


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("time-terms")


@pytest.fixture(scope="module")
def lake(work: Path) -> Path:
    return truth_survey("lake", LAKE_TIDE, 1, 4 * 3600.0, work / "lake")


def truth_current(scenario: str, effects: list[str], xy: np.ndarray, utc: float) -> np.ndarray:
    """The simulator's true current (east, north) at local places `xy` and UNIX time `utc`."""
    s = sc.load(scenario)
    w = World(s, fx.parse_list(effects), 3600.0)
    e, n = w.current(xy[:, 0], xy[:, 1], np.full(len(xy), utc - s.t0))
    return np.column_stack([e, n])


def fit_tide(lake: Path) -> None:
    """`forcemap fit LAKE --target current_speed --effects tide`, as a user runs it; it must succeed."""
    argv = ["fit", str(lake), "--target", "current_speed", "--effects", "tide", "--quiet", "--no-plots"]
    assert main(argv) == 0


def test_tide_amplitude_and_phase_come_back_with_an_sd_that_covers_them(lake: Path) -> None:
    survey = read_survey(lake)
    base = survey.fit("current_east")
    fit = survey.fit("current_east", effects="tide")
    (m2,) = constituents(fit.model_.primary)  # a 4-hour record: M2 alone, the semidiurnal band
    assert m2["name"] == "M2"
    assert abs(m2["amplitude"] - 0.5) <= 2 * m2["amplitude_sd"] + 1e-3
    assert abs((m2["phase_deg"] - 200 + 180) % 360 - 180) <= 2 * m2["phase_sd_deg"] + 0.1
    assert m2["amplitude_sd"] < 0.02 and m2["phase_sd_deg"] < 3
    # and the error falls to the measurement noise (0.037 m/s)
    assert fit.cv_rmse < 0.5 * base.cv_rmse and fit.cv_rmse < 0.06
    # the speed's tidal ellipse: along the lake's flow (90 deg), rectilinear, the same phase
    speed = survey.fit("current_speed", effects="tide").tide()
    (e,) = speed["ellipses"]
    assert abs(e["major"] - 0.5) <= 2 * e["major_sd"] + 2e-3
    assert abs(e["direction_deg"] - 90) <= 2 * e["direction_sd_deg"] + 0.5
    assert abs(e["minor"]) <= 2 * e["minor_sd"] + 2e-3
    assert abs((e["phase_deg"] - 200 + 180) % 360 - 180) <= 2 * e["phase_sd_deg"] + 0.5


def test_fit_at_a_time_predicts_tomorrows_current(lake: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    code = main(["fit", str(lake), "--target", "current_east", "--effects", "tide", "--at", TOMORROW,
                 "--json", "-", "--quiet", "--no-plots"])  # fmt: skip
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    at = report["at"]
    assert at["time"] == "2026-06-02T14:00:00Z" and at["unix_s"] == parse_at(TOMORROW)
    truth = truth_current("lake", LAKE_TIDE, np.zeros((1, 2)), at["unix_s"])[0, 0]
    assert abs(at["mean"] - truth) < 0.03, (at, truth)
    assert any("tidal prediction" in n for n in at["notes"])
    # the baseline fitted since: a GP in time says it has reverted to its mean there
    code = main(["fit", str(lake), "--target", "current_east", "--effects", "t", "--at", TOMORROW,
                 "--json", "-", "--quiet", "--no-plots"])  # fmt: skip
    gp = json.loads(capsys.readouterr().out)["at"]
    assert any("reverted to its mean" in n for n in gp["notes"])
    assert abs(gp["mean"] - truth) > 0.1  # and it is not tomorrow's current


def test_api_and_grid_at_a_time(lake: Path, work: Path) -> None:
    survey = read_survey(lake)
    fit = survey.fit("current_speed", effects="tide")
    lat, lon = survey.table.columns["lat"][:50], survey.table.columns["lon"][:50]
    at = parse_at(TOMORROW)
    p = fit.predict(lat, lon, at=TOMORROW)
    truth = truth_current("lake", LAKE_TIDE, survey.table.xy[:50], at)
    assert np.abs(p["east"] - truth[:, 0]).max() < 0.03
    # one time per place: six hours apart the flood has turned to the ebb
    times = at + np.linspace(0, 6 * 3600, 50)
    p2 = fit.predict(lat, lon, at=times)
    truth2 = np.array(
        [
            truth_current("lake", LAKE_TIDE, survey.table.xy[i : i + 1], t)[0]
            for i, t in enumerate(times)
        ]
    )
    assert np.abs(p2["east"] - truth2[:, 0]).max() < 0.03
    assert np.sign(truth2[0, 0]) != np.sign(truth2[-1, 0]) or np.ptp(truth2[:, 0]) > 0.3
    import xarray  # noqa: F401  (the [gis] extra, in the test extras: a missing one fails)
    ds = fit.to_xarray(resolution=10.0, at=TOMORROW)
    assert float(ds["time"]) == at and "asked for" in ds["time"].attrs["long_name"]
    assert ds.attrs["forcemap_map_time"] == "2026-06-02T14:00:00Z"
    east = ds["current_east"]
    assert abs(float(east.mean()) - truth[:, 0].mean()) < 0.05
    out = work / "maps.nc"
    fit_tide(lake)
    code = main(["grid", str(lake), "-o", str(out), "--target", "current_speed", "--at", TOMORROW,
                 "--resolution", "10", "--quiet"])  # fmt: skip
    assert code == 0
    import xarray as xr

    with xr.open_dataset(out, decode_times=False) as saved:
        assert float(saved["time"]) == at  # the workspace's tide fit, at tomorrow's time
        assert abs(float(saved["current_east"].mean()) - truth[:, 0].mean()) < 0.05


@pytest.mark.parametrize("command", ["fit", "grid", "plan"])
def test_a_bad_at_is_one_line_and_exit_2(lake: Path, work: Path, command: str, capsys) -> None:  # type: ignore[no-untyped-def]
    args = {
        "fit": ["--target", "current_east", "--no-plots"],
        "grid": ["-o", str(work / "bad.nc")],
        "plan": ["--mission", "lawnmower", "-o", str(work / "bad-plan"), "--scenario", "lake"],
    }[command]
    capsys.readouterr()
    assert main([command, str(lake), *args, "--at", "2026-06-02T14:00", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "time zone" in err[0]
    assert not (work / "bad.nc").exists() and not (work / "bad-plan.waypoints").exists()


@pytest.fixture(scope="module")
def day(work: Path) -> Path:
    return truth_survey("river", RIVER_TIDE, 1, 24 * 3600.0, work / "day", every_s=10.0)


def _split(table: Path, share: float) -> tuple[Path, np.ndarray]:
    """The first `share` of a table's time as a table of its own, and the rows after it."""
    lines = table.read_text().splitlines()
    t = np.array([float(r.split(",", 1)[0]) for r in lines[1:]])
    cut = t[0] + share * (t[-1] - t[0])
    head = table.with_name(f"first{int(100 * share)}.csv")
    head.write_text(
        "\n".join([lines[0]] + [r for r, ti in zip(lines[1:], t, strict=True) if ti <= cut]) + "\n"
    )
    return head, np.flatnonzero(t > cut)


def _errors(sm: SurveyModel, survey, rows: np.ndarray) -> float:
    """RMSE of the model's current speed against the measured one at `rows` of `survey`, each at its time
    (the places in the model's own local frame)."""
    c = survey.columns
    xy = np.column_stack(
        LocalFrame(sm.survey.lat0, sm.survey.lon0).to_local(c["lat"][rows], c["lon"][rows])
    )
    pred = sm.predict_grid(xy, c["t"][rows])["mean"]
    measured = np.hypot(survey.columns["current_east"][rows], survey.columns["current_north"][rows])
    return float(np.sqrt(np.mean((pred - measured) ** 2)))


def test_a_tide_fitted_on_60_percent_of_a_day_predicts_the_rest(day: Path) -> None:
    head, later = _split(day, 0.6)
    whole = read_survey(day).table
    train = read_survey(head)
    inside = np.arange(train.n)
    ratios = {}
    for effect in ("tide", "t"):
        sm = train.fit("current_speed", effects=effect).model_
        ratios[effect] = _errors(sm, whole, later) / _errors(sm, whole, inside)
        if effect == "tide":  # 14.4 h: M2 alone, the semidiurnal band
            assert [c["name"] for c in constituents(sm.primary)] == ["M2"]
    assert ratios["tide"] <= 1.5, ratios
    assert ratios["t"] > 1.5 * 1.5, ratios  # a GP over t reverts to its mean: it cannot


@pytest.fixture(scope="module")
def seiche(work: Path) -> Path:
    return truth_survey("lake", ["seiche"], 1, 3.5 * 3600.0, work / "seiche")


def test_the_seiche_period_comes_back_within_its_sd(seiche: Path) -> None:
    survey = read_survey(seiche)
    base = survey.fit("current_speed")
    fit = survey.fit("current_speed", effects="seiche")
    s = fit.tide()["seiche"]
    assert s["estimated"] and s["period_sd_s"] < 60
    assert abs(s["period_s"] - 4440.0) <= 2 * s["period_sd_s"]  # the simulator's 74 min
    assert s["fap"] < 1e-3
    assert any(t.startswith("seiche(44") for t in fit.model_.terms)  # recorded with its period
    assert fit.cv_rmse < 0.8 * base.cv_rmse
    assert "Merian" in s["text"]
    # the recorded term refits to the same period, without estimating it again
    again = survey.fit("current_speed", terms=fit.model_.terms)
    assert again.tide()["seiche"]["estimated"] is False
    assert math.isclose(again.tide()["seiche"]["period_s"], s["period_s"], rel_tol=1e-4)


def test_tide_on_depth_is_the_water_level(work: Path) -> None:
    """The simulator's tide moves the surface 0.7 m with M2's period: `tide` on depth is that level, and
    the depth map's datum says so."""
    from forcemap.host.workbench.depth.water_level import level_estimate, map_datum

    table = truth_survey("river", ["tide"], 1, 3 * 3600.0, work / "level")
    survey = read_survey(table)
    base = survey.fit("depth")
    fit = survey.fit("depth", effects="tide")
    sm = fit.model_
    level, sd = level_estimate(sm.primary, sm.survey.trel)
    truth = np.load(table.parent / "truth" / "samples.npz")
    true_level = np.interp(sm.survey.columns["t"], truth["t"], truth["water_level"])
    true_level -= true_level.mean()
    assert np.sqrt(np.mean((level - true_level) ** 2)) < 0.05  # of a 1.4 m range
    assert fit.result_.crossline["crossline_rmse"] < 0.5 * base.result_.crossline["crossline_rmse"]
    assert "tidal fit (tide)" in map_datum(sm.survey, sm.terms)
    assert "2026-06-02T14:00Z" in map_datum(sm.survey, sm.terms, parse_at(TOMORROW))


def test_plan_start_reads_the_tide_along_the_mission(lake: Path, work: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    fit_tide(lake)
    out = work / "lake-plan"
    capsys.readouterr()
    code = main(["plan", str(lake), "--mission", "lawnmower", "--scenario", "lake", "-o", str(out),
                 "--start", TOMORROW, "--json", "-", "--quiet"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0, captured.err
    report = json.loads(captured.out)
    assert report["start"] == "2026-06-02T14:00:00Z"
    assert "when the boat is on it" in captured.err  # the note: the field in time along the mission
    assert (work / "lake-plan.waypoints").exists()
