"""`forcemap season`: exact on Dask (a LocalCluster started and stopped here), right on a simulated season
(scales, static depth, staleness), and bad logs left out one line each."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from forcemap.host.cli import main
from forcemap.host.extras import install_hint
from forcemap.host.season.engine import DaskRunner, LocalRunner
from forcemap.host.season.run import run_season
from forcemap.host.season.staleness import message, plan_note
from forcemap.sim_devices.season import make_season
from scipy import stats


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


@pytest.fixture(scope="module")
def twenty(tmp_path_factory) -> list[Path]:
    return make_season(20, 30, tmp_path_factory.mktemp("twenty"), samples=400, seed=3)


def test_dask_local2_equals_one_process(twenty):
    one = run_season(twenty, LocalRunner(), n_basis=120, cv=False)
    dask = DaskRunner("local:2")
    try:
        assert dask.workers == 2
        two = run_season(twenty, dask, n_basis=120, cv=False)
        # no task failed on the way (a map without a reduction once summed its footprints and failed)
        logs = dask.client.get_worker_logs()
        assert not [m for w in logs.values() for _, m in w if "Compute Failed" in m]
    finally:
        dask.close()
    assert "Dask, 2 worker(s)" in two.runner
    assert len(one.surveys) == len(two.surveys) == 20
    for key in one.total:
        a, b = one.total[key], two.total[key]
        assert a.n == b.n
        for m in ("G", "B", "R"):
            assert _rel(getattr(b, m), getattr(a, m)) <= 1e-10
    for r1, r2 in zip(one.surveys, two.surveys, strict=True):
        assert r1.path == r2.path
        assert _rel(r2.stats["current"].G, r1.stats["current"].G) <= 1e-10
    assert _rel(two.depth.theta, one.depth.theta) <= 1e-6
    assert _rel(two.current.theta, one.current.theta) <= 1e-6
    assert _rel(two.current.scales, one.current.scales) <= 1e-6
    assert _rel(two.depth.post.mean, one.depth.post.mean) <= 1e-6
    assert _rel(two.current.post.mean, one.current.post.mean) <= 1e-6
    for w1, w2 in zip(one.wind, two.wind, strict=True):
        assert _rel(w2[0].mean, w1[0].mean) <= 1e-6


@pytest.fixture(scope="module")
def season(tmp_path_factory):
    folder = tmp_path_factory.mktemp("season")
    paths = make_season(10, 30, folder, samples=3000, seed=5)
    return run_season(paths, LocalRunner(), cv=True), json.loads(
        (folder / "season_truth.json").read_text()
    )


def test_scales_follow_the_true_discharge_within_5_percent(season):
    s, truth = season
    q = np.array([t["discharge_scale"] for t in truth["surveys"]])
    q = q / q.mean()
    # the hydrograph spans a wide range, so a constant scale could not pass
    assert q.max() / q.min() > 2.0
    assert np.all(np.abs(s.current.scales / q - 1.0) < 0.05), (s.current.scales, q)


def test_static_depth_beats_every_survey_own_map_in_blocked_cv(season):
    s, _ = season
    assert len(s.cv) == 10
    for c in s.cv:
        assert c["rmse_static"] < c["rmse_own"], c


def test_staleness_rises_with_age_and_with_the_change_in_discharge(season):
    s, _ = season
    st = s.stale
    assert len(st.rmse) == 45
    rho_age, p_age = stats.spearmanr(st.age_days, st.rmse)
    rho_q, p_q = stats.spearmanr(st.dscale, st.rmse)
    assert rho_age > 0.2 and p_age < 0.05
    assert rho_q > 0.7 and p_q < 1e-6
    assert st.per_day > 0 and st.doubling_days is not None and st.doubling_days > 0
    # a map predicting a day of nearly the same discharge is much better than one of a very different day
    near, far = st.rmse[st.dscale < 0.1], st.rmse[st.dscale > 0.4]
    assert near.mean() < 0.5 * far.mean()


def test_cli_season_writes_the_season_and_plan_reads_its_half_life(tmp_path, capsys):
    src = tmp_path / "sim"
    assert main(["sim", "--season", "4", "--days", "8", "--samples", "1500", "-o", str(src)]) == 0
    assert len(list(src.glob("survey-*/samples.parquet"))) == 4
    assert len(json.loads((src / "season_truth.json").read_text())["surveys"]) == 4
    out = tmp_path / "out"
    code = main(
        ["season", str(src / "*" / "samples.parquet"), "-o", str(out), "--quiet", "--no-cv"]
    )
    assert code == 0
    data = json.loads((out / "season.json").read_text())
    assert len(data["surveys"]) == 4 and data["rejected"] == []
    assert "Season" in (out / "season.html").read_text()
    maps = np.load(out / "maps.npz")
    assert maps["depth"].shape == maps["depth_sd"].shape and np.all(maps["depth_sd"] > 0)
    assert maps["wind_east"].shape[0] == 4
    # a second run into the same folder needs --force
    capsys.readouterr()
    assert main(["season", str(src / "*" / "samples.parquet"), "-o", str(out), "--quiet"]) == 2
    assert "--force" in capsys.readouterr().err
    d = data["staleness"]["doubling_age_days"]
    t_last = data["surveys"][0]["t1"]
    note = plan_note(out, t_last, t_last + 9 * 86400)
    assert note == message(9.0, d) and note.startswith("this map is 9 days old")


def _write(path: Path, cols: dict) -> Path:
    pq.write_table(pa.table(cols), path)
    return path


def test_bad_logs_are_left_out_one_line_each_and_the_season_stands(tmp_path, capsys):
    from forcemap.sim_devices.offline import make_survey

    paths = make_season(4, 6, tmp_path / "sim", samples=1500, seed=2)
    good = pq.read_table(paths[0]).to_pydict()
    far = dict(good, lat=[v + 0.5 for v in good["lat"]])  # 55 km north: another river
    blind = {k: v for k, v in good.items() if k not in ("lat", "lon")}
    bad = tmp_path / "bad"
    bad.mkdir()
    inputs = [
        _write(bad / "far.parquet", far),
        _write(bad / "blind.parquet", blind),
        bad / "corrupt.mcap",
    ]
    inputs[2].write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 8)
    # a real MCAP log of the daemon (simulated instruments through the pipeline) joins the tables
    make_survey("river", [], seed=1, duration_s=90, out_dir=tmp_path / "mcap")
    log = next((tmp_path / "mcap" / "logs").glob("*.mcap"))
    out = tmp_path / "out"
    args = ["season", *map(str, paths), str(log), *map(str, inputs), "-o", str(out), "--quiet"]
    assert main([*args, "--no-cv"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    left = [line for line in err if line.startswith("left out:")]
    assert len(left) == 3
    assert any("far.parquet" in x and "another river" in x for x in left)
    assert any("blind.parquet" in x for x in left)
    assert any("corrupt.mcap" in x for x in left)
    data = json.loads((out / "season.json").read_text())
    assert len(data["surveys"]) == 5
    assert str(log) in [s["path"] for s in data["surveys"]]
    assert len(data["rejected"]) == 3


def test_nothing_usable_and_a_missing_dask_are_one_line_and_exit_2(tmp_path, capsys, monkeypatch):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a log")
    assert main(["season", str(junk), "-o", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no usable log" in err[0]
    assert main(["season", str(tmp_path / "none*.csv"), "-o", str(tmp_path / "o")]) == 2
    assert "matches no file" in capsys.readouterr().err
    paths = make_season(2, 2, tmp_path / "sim", samples=300, seed=1)
    monkeypatch.setitem(sys.modules, "distributed", None)
    assert main(["season", *map(str, paths), "-o", str(tmp_path / "o"), "--dask", "local:2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and install_hint("dask") in err[0]
    shutil.rmtree(tmp_path / "sim")


def test_plan_with_a_folder_that_holds_no_season_is_one_line_before_any_fit(tmp_path, capsys):
    [table] = make_season(1, 1, tmp_path / "sim", samples=400, seed=1)
    empty = tmp_path / "not-a-season"
    empty.mkdir()
    args = ["plan", str(table), "--mission", "lawnmower", "-o", str(tmp_path / "p")]
    assert main([*args, "--season", str(empty)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a season" in err[0] and "forcemap season" in err[0]
    assert not (tmp_path / "sim" / "survey-000" / "samples.parquet.forcemap").exists()
    assert main([*args, "--season", str(empty), "--at", "June 3"]) == 2
    assert "YYYY-MM-DD" in capsys.readouterr().err
