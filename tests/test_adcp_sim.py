"""The simulated ADCP (issue 32): PD0 of the simulated river's true current profile, read back by
`forcemap import`; side by side with the paddle wheels of the same run; and the ADCP's table through
fit, diagnose, grid, report and season like any survey."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from forcemap.host.cli import main

from tests.tools import IN_CI

try:
    import mhkit  # noqa: F401
except ImportError:
    if IN_CI:
        raise
    pytest.skip('needs pip install ".[adcp]"', allow_module_level=True)

from forcemap.host.convert.adcp import process  # noqa: E402
from forcemap.host.convert.adcp_qa import findings  # noqa: E402
from forcemap.host.convert.adcp_read import read_pd0  # noqa: E402
from forcemap.sim_devices.adcp import AdcpSetup, SimAdcp, read_truth, write_pd0  # noqa: E402
from forcemap.sim_devices.offline import make_survey  # noqa: E402

COMPASS_ERROR = 6.0  # the ADCP's compass reads 6 deg clockwise of the truth
BT_LOSS = 0.10


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One simulated river survey (paddle wheels through the daemon's pipeline) and the ADCP's PD0
    of the same run, with bottom-track loss, a compass error and a clock 2.5 s slow."""
    out = tmp_path_factory.mktemp("adcp_sim")
    wheels = make_survey("river", ["depth_current"], seed=1, duration_s=600, out_dir=out)
    truth = read_truth(out / "truth" / "samples.csv")
    setup = AdcpSetup(compass_error_deg=COMPASS_ERROR, bt_loss=BT_LOSS, clock_error_s=-2.5, seed=3)
    data, per_ens = SimAdcp(setup).record(truth)
    pd0 = write_pd0(out / "river.PD0", data)
    return {"dir": out, "wheels": wheels, "truth": truth, "pd0": pd0, "ens": per_ens}


def _table(path) -> dict[str, np.ndarray]:
    rows = list(csv.DictReader(open(path)))
    return {k: np.array([float(r[k]) if r[k] else math.nan for r in rows]) for k in rows[0]}


def test_round_trip_recovers_the_depth_averaged_current(run):
    s = process(read_pd0(run["pd0"]))
    ens = run["ens"]
    assert s.clock.offset_s == pytest.approx(2.5, abs=0.02)
    assert s.compass.offset_deg == pytest.approx(-COMPASS_ERROR, abs=0.5)
    te = np.interp(s.t, ens["t"], ens["davg_e"])
    tn = np.interp(s.t, ens["t"], ens["davg_n"])
    ok = np.isfinite(s.davg_e)
    rms = math.sqrt(np.mean((s.davg_e[ok] - te[ok]) ** 2 + (s.davg_n[ok] - tn[ok]) ** 2))
    assert rms < 0.02, rms
    assert ok.mean() > 0.6  # the rest: too shallow for two cells, or bottom track lost in a turn
    no_bt = {f.check: f for f in findings(s)}["no_bottom_track"]
    assert no_bt.value == pytest.approx(100 * BT_LOSS, abs=2.0) and no_bt.verdict != "green"
    # the bottom track agrees with the GPS once the offset is applied: no moving bed in the river
    mb = {f.check: f for f in findings(s)}["moving_bed"]
    assert mb.verdict == "green" and mb.value < 0.02


def test_side_by_side_with_the_paddle_wheels(run, tmp_path):
    """The ADCP's near-surface cell and the paddle wheels of the same run see the same river: within
    0.15 m/s RMS at the same times, the ADCP a little weaker (its cell lies below the surface, where
    the power-law profile is slower) and its depth average weaker still (6/7 of the surface)."""
    mcap = tmp_path / "adcp.mcap"
    assert main(["import", str(run["pd0"]), "-o", str(mcap)]) == 0
    assert main(["export", str(mcap), "-o", str(tmp_path / "adcp.csv")]) == 0
    a, w = _table(tmp_path / "adcp.csv"), _table(run["wheels"])
    k = np.clip(np.searchsorted(w["t"], a["t"]), 0, w["t"].size - 1)
    near = np.abs(w["t"][k] - a["t"]) < 0.5
    both = near & np.isfinite(a["current_east"]) & np.isfinite(w["current_east"][k])
    assert both.sum() > 200
    de = a["current_east"][both] - w["current_east"][k][both]
    dn = a["current_north"][both] - w["current_north"][k][both]
    assert math.sqrt(np.mean(de**2 + dn**2)) < 0.15
    ns = np.hypot(a["current_east"], a["current_north"])[both]
    wheel = np.hypot(w["current_east"], w["current_north"])[k][both]
    davg = np.hypot(a["current_east_davg"], a["current_north_davg"])[both]
    assert np.mean(davg) < np.mean(ns) < np.mean(wheel)
    assert np.mean(davg) / np.mean(wheel) == pytest.approx(6 / 7, abs=0.05)


@pytest.mark.slow
def test_an_adcp_survey_goes_through_fit_diagnose_grid_report_and_season(run, tmp_path):
    mcap = tmp_path / "adcp.mcap"
    assert main(["import", str(run["pd0"]), "-o", str(mcap)]) == 0
    table = tmp_path / "adcp.csv"
    assert main(["export", str(mcap), "-o", str(table)]) == 0
    assert main(["fit", str(table), "--target", "current_speed_davg", "--no-plots"]) == 0
    out = tmp_path / "d.json"
    cmd = ["diagnose", str(table), "--target", "current_speed_davg", "--rounds", "1"]
    assert main([*cmd, "--json", str(out)]) == 0
    first = json.loads(out.read_text())["rounds"][0]
    assert first["missing_effect_found"] and "depth" in first["added"]  # the simulated effect
    assert main(["grid", str(table), "-o", str(tmp_path / "grid")]) == 0
    assert any((tmp_path / "grid").glob("*.tif"))
    assert main(["report", str(table), "-o", str(tmp_path / "r.html")]) == 0
    # a second survey of the same reach a day later, with another compass error
    truth = dict(run["truth"])
    truth["t"] = truth["t"] + 86400.0
    data, _ = SimAdcp(AdcpSetup(compass_error_deg=-4.0, bt_loss=0.05, seed=5)).record(truth)
    mcap2 = tmp_path / "adcp2.mcap"
    assert main(["import", str(write_pd0(tmp_path / "day2.PD0", data)), "-o", str(mcap2)]) == 0
    season = tmp_path / "season"
    assert main(["season", str(mcap), str(mcap2), "-o", str(season), "--quiet"]) == 0
    assert len(json.loads((season / "season.json").read_text())["surveys"]) == 2


def test_sim_records_an_adcp_beside_the_truth(tmp_path, capsys):
    out = tmp_path / "truth"
    cmd = ["sim", "--scenario", "river", "--duration", "4m", "-o", str(out)]
    assert main([*cmd, "--adcp", "bt_loss=0.1,compass_error_deg=6,seed=2"]) == 0
    assert main(["import", str(out / "adcp.PD0"), "-o", str(tmp_path / "a.mcap")]) == 0
    s = process(read_pd0(out / "adcp.PD0"))
    assert s.compass.offset_deg == pytest.approx(-6.0, abs=1.0)
    capsys.readouterr()
    assert main([*cmd, "--force", "--adcp", "compass=6"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "compass_error_deg" in err[0]
