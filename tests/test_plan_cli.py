"""Mission files, the boat model's overrides, `forcemap sim --mission FILE.waypoints` offline, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.plan.boat_model import BoatModel, load_boat
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel import waypoints as wp
from forcemap.host.vessel.geodesy import LocalFrame

XY = np.array([[-150.0, -20.0], [50.0, -20.0], [50.0, 10.0], [-150.0, 10.0]])


def write_file(tmp: Path, speeds=None) -> Path:  # type: ignore[no-untyped-def]
    scen = sc.load("river")
    path = tmp / "m.waypoints"
    ms.save_waypoints(
        path, ms.Mission("m", "", XY, False, speeds), LocalFrame(scen.lat0, scen.lon0)
    )
    return path


def test_waypoint_file_round_trip(tmp_path: Path) -> None:
    path = write_file(tmp_path, np.array([np.nan, 5.0, 5.0, 3.0]))
    assert path.read_text().splitlines()[0] == "QGC WPL 110"
    home, items = wp.read_wpl(path)
    assert [i.command for i in items] == [16, 178, 16, 16, 178, 16]
    assert [i.params[1] for i in items if i.command == 178] == [5.0, 3.0]
    m = ms.load(str(path), sc.load("river"))
    # six decimals of a degree in the file: 0.11 m
    assert np.abs(m.waypoints - XY).max() < 0.12
    assert m.loop is False and np.allclose(m.speeds, [np.nan, 5.0, 5.0, 3.0], equal_nan=True)
    assert list(m.seqs) == [1, 3, 4, 6]


def test_sim_offline_flies_a_waypoint_file_and_records_it(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    path = write_file(tmp_path)
    truth = tmp_path / "truth"
    assert main(["sim", "--mission", str(path), "--duration", "150s", "-o", str(truth)]) == 0
    assert not (tmp_path / "ports").exists()
    _, flown = wp.read_wpl(truth / "mission.waypoints")
    _, given = wp.read_wpl(path)
    assert flown == given
    doc = json.loads((truth / "mission.json").read_text())
    assert len(doc["waypoints"]) == 4 and len(doc["lines"]) == 3
    assert doc["waypoints"][1]["x"] == pytest.approx(50.0, abs=0.12)
    assert doc["lines"][0]["latlon"][0][0] == pytest.approx(doc["waypoints"][0]["lat"])
    rows = np.genfromtxt(truth / "samples.csv", delimiter=",", names=True)
    assert len(rows) == 1500  # 150 s at 10 Hz
    # the boat flew the first leg east along y = -20 (downstream: a few metres off, as in Fig. 2)
    assert abs(np.median(rows["y"][200:500]) + 20.0) < 5.0 and rows["x"].max() > 40.0


def test_sim_without_ports_needs_truth(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["sim", "--duration", "10s"]) == 2
    assert "-o DIR" in capsys.readouterr().err


def test_boat_model_overrides(tmp_path: Path) -> None:
    default = BoatModel()
    assert 5.3 < default.max_speed < 5.7 and default.cruise_speed == 3.5
    f = tmp_path / "boat.toml"
    f.write_text("[boat]\nmax_speed = 4.5\nturn_rate_deg_s = 30\n[controller]\nlookahead_m = 15\n")
    m = load_boat(f)
    assert m.max_speed == pytest.approx(4.5, abs=1e-6)
    assert m.turn_rate() == pytest.approx(30.0, abs=0.5)
    assert m.gains.lookahead_m == 15.0


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("[hull]\nwings = 2\n", "unknown key"),
        ("[boat]\nspeed = 3\n", "unknown key"),
        ("[boat\n", "cannot read"),
    ],
)
def test_plan_refuses_bad_boat_files(tmp_path: Path, capsys, text: str, needle: str) -> None:  # type: ignore[no-untyped-def]
    table = tmp_path / "t.csv"
    table.write_text("t,lat,lon\n")
    boat = tmp_path / "boat.toml"
    boat.write_text(text)
    path = write_file(tmp_path)
    code = main(
        ["plan", str(table), "--mission", str(path), "-o", str(tmp_path / "p"), "--boat", str(boat)]
    )
    err = capsys.readouterr().err
    assert code == 2 and needle in err and len(err.strip().splitlines()) == 1


def test_plan_refuses_a_bad_mission(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    table = tmp_path / "t.csv"
    table.write_text("t,lat,lon\n")
    bad = tmp_path / "bad.waypoints"
    bad.write_text("QGC WPL 110\n0\t1\t0\t16\n")
    code = main(["plan", str(table), "--mission", str(bad), "-o", str(tmp_path / "p")])
    err = capsys.readouterr().err
    assert code == 2 and "cannot read the mission" in err and len(err.strip().splitlines()) == 1


def test_plan_output_folder_names_the_files_like_the_mission(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """-o FOLDER (an existing folder) writes FOLDER/MISSION-planned.*; they too need --force."""
    table = tmp_path / "t.csv"
    table.write_text("t,lat,lon\n")
    folder = tmp_path / "plans"
    folder.mkdir()
    (folder / "lawnmower-planned.waypoints").write_text("keep me\n")
    assert main(["plan", str(table), "--mission", "lawnmower", "-o", str(folder)]) == 2
    err = capsys.readouterr().err
    assert "lawnmower-planned.waypoints exists; pass --force" in err
    assert (folder / "lawnmower-planned.waypoints").read_text() == "keep me\n"
