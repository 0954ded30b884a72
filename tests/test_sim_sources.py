"""Issue 20 on the simulator, whose truth is known: an NMEA-only boat with two GNSS receivers on one
talker, the instrument bus re-sending the fix at 3 decimals, a fluxgate and a damped compass, a rate
of turn sentence, and false echoes in deep water. One source per quantity keeps every figure as good
as with one clean source of each kind."""

from __future__ import annotations

import json

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.log.mcap import read_messages
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.offline import run_to_mcap

from tests.sim_sources import figures, run

DURATION_S = 600.0


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """One GNSS, one compass, one speed log, the sounder: one clean source of each kind."""
    paths, truth, _ = run(tmp_path_factory.mktemp("clean"), None, duration_s=DURATION_S)
    return paths, figures(paths, truth)


@pytest.fixture(scope="module")
def faulty(tmp_path_factory):
    paths, truth, sim = run(tmp_path_factory.mktemp("faulty"), "sources", duration_s=DURATION_S)
    return paths, figures(paths, truth), sim


def _sources_meta(paths) -> dict:
    from mcap.reader import make_reader

    with open(paths[-1], "rb") as f:
        metas = [m for m in make_reader(f).iter_metadata() if m.name == "sources"]
    return {q: json.loads(v) for q, v in metas[-1].metadata.items()}


def test_speed_from_successive_positions_agrees_with_sog(faulty):
    _, fig, sim = faulty
    assert sim.meta()["instruments"]["nmea_bus"] == [
        "rate_of_turn",
        "relay_position",
        "second_compass",
        "second_gnss",
    ]
    assert fig["rows"] > 0.9 * DURATION_S
    assert fig["speed_vs_sog_p95"] < 0.5


def test_yaw_rate_p99_is_the_truths(faulty):
    _, fig, _ = faulty
    assert abs(fig["yaw_rate_p99"] - fig["truth_yaw_rate_p99"]) < 2.0
    assert fig["truth_yaw_rate_p99"] > 10.0  # the survey turns: the figure means something


def test_the_current_is_no_worse_than_with_one_clean_source_of_each_kind(clean, faulty):
    assert faulty[1]["current_rows"] >= 0.95 * clean[1]["current_rows"]
    # the two runs share the world and each device's noise; 2 % for the sounder's extra draws
    assert faulty[1]["current_rmse"] <= 1.02 * clean[1]["current_rmse"]


def test_the_log_says_which_source_was_used_and_the_second_receiver_is_1_s_late(faulty):
    meta = _sources_meta(faulty[0])
    pos = meta["position"]
    assert pos["chosen"] == "nmea GPRMC [hhmmss.ss 5dp]"
    late = pos["sources"]["nmea GPRMC [hhmmss 3dp]"]
    assert late["used"] == 0 and late["rate_hz"] == pytest.approx(0.5, abs=0.01)
    assert late["latency_s"] == pytest.approx(1.0, abs=0.25)
    assert late["lag_s"] == pytest.approx(1.0, abs=0.25)
    assert 1.0 < late["diff_median"] < 8.0  # the antenna 2 m away, 1 s late at ~3 m/s
    relay = pos["sources"]["nmea IIRMC [hhmmss 3dp]"]
    assert relay["used"] == 0 and relay["diff_p95"] < 2.0  # 3-decimal minutes: 1.85 m steps
    assert meta["heading"]["chosen"] == "nmea HCHDG +variation"
    assert meta["heading"]["sources"]["nmea IIHDT"]["lag_s"] > 0.5  # the damped one lags
    assert meta["yaw_rate"]["chosen"] == "nmea TIROT"


def test_log_info_shows_two_receivers_and_two_compasses(faulty, capsys):
    path = str(faulty[0][-1])
    assert main(["log", "info", path]) == 0
    text = capsys.readouterr().out
    section = text[text.index("sources per quantity") :]
    for name in (
        "* nmea GPRMC [hhmmss.ss 5dp]",
        "nmea GPRMC [hhmmss 3dp]",
        "nmea IIRMC [hhmmss 3dp]",
        "* nmea HCHDG +variation",
        "nmea IIHDT",
        "* nmea TIROT",
    ):
        assert name in section, name
    assert "best by the default quality order" in section and "lag +1." in section
    assert main(["log", "info", path, "--json", "-"]) == 0
    (info,) = json.loads(capsys.readouterr().out)
    hdt = info["sources"]["heading"]["sources"]["nmea IIHDT"]
    assert hdt["diff_p95"] > 2.0 and hdt["used"] == 0
    assert len(info["sources"]["position"]["sources"]) == 4


def test_a_boat_file_priority_takes_the_relay_and_the_speed_check_catches_it(tmp_path):
    boat = '[sources]\nposition = ["IIRMC"]\n'
    paths, truth, _ = run(tmp_path, "sources", duration_s=300.0, boat_toml=boat)
    assert _sources_meta(paths)["position"]["chosen"] == "nmea IIRMC [hhmmss 3dp]"
    assert figures(paths, truth)["speed_vs_sog_p95"] > 0.5  # 1.85 m steps each second


def test_false_echoes_in_deep_water(tmp_path):
    sim = Simulation(
        scenario="deep", faults="false_echoes:rate=0.2", seed=2, truth_dir=tmp_path / "t"
    )
    paths = run_to_mcap(sim, 240.0, tmp_path / "logs", seed=2, ports=("depth",), boat=None)
    truth = np.genfromtxt(tmp_path / "t" / "samples.csv", delimiter=",", names=True)
    assert truth["depth"].min() > 70.0 and truth["depth"].max() <= 100.0
    dpt = [
        m.message["depth"] for m in read_messages(paths, "/depth") if m.message["sentence"] == "DPT"
    ]
    shallow = sum(d < 21.0 for d in dpt)
    assert shallow == sim.sounder.false_echoes > 0.05 * len(dpt)
