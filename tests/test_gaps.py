"""Gaps in a target are not a refusal (issue 36 item 2): a target missing on some rows is mapped from the
rows that have it, and every command says how many were left out and where.

The counts are checked against the table's own empty cells, read with the csv module (what any reader of
the table sees), not against another number of forcemap's; the stretches against the times of the rows
the test blanked, or the table's own longest run of empty cells."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from forcemap.host.cli import main
from forcemap.host.season.engine import LocalRunner
from forcemap.host.season.run import run_season
from forcemap.host.workbench.engine import fourier
from forcemap.host.workbench.survey.gaps import correlation_time
from forcemap.host.workbench.survey.table import load_survey
from forcemap.sim_devices.season import make_season

from bench.inject_cases import FJORD
from bench.synth_survey import make_survey
from tests.tools import csv_rows, write_csv_rows


def _run(capsys, argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _empty(path: Path, columns: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Each row's time (s since the first) and whether any of `columns` is empty there."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["t"]) for r in rows])
    empty = np.array([any(r[c] in ("", "nan") for c in columns) for r in rows])
    return t - t[0], empty


def _longest_run(t: np.ndarray, empty: np.ndarray) -> tuple[float, float]:
    """Start and end (min) of the first longest run of consecutive empty rows."""
    best, i = (0, -1), 0
    while i < len(empty):
        if not empty[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(empty) and empty[j + 1]:
            j += 1
        if j - i > best[1] - best[0]:
            best = (i, j)
        i = j + 1
    return t[best[0]] / 60.0, t[best[1]] / 60.0


# ---- a real fjord race: the speed log and the sounder drop out


@pytest.fixture(scope="module")
def fjord(real_case) -> Path:
    """The real race imported and exported once per run (tests/real_cases.py, shared with the other modules):
    its current and depth have gaps of their own."""
    return real_case(FJORD).csv


@pytest.mark.slow
def test_fit_and_grid_of_a_real_log_use_the_rows_that_have_the_target(fjord, capsys, tmp_path):
    table = tmp_path / fjord.name
    table.write_bytes(fjord.read_bytes())
    # depth's gaps are the API test's (one fit of the 10,542 rows each)
    for target, cols in (("current_speed", ["current_east", "current_north"]),):
        t, empty = _empty(table, cols)
        assert 0 < empty.sum() < 0.1 * len(empty)  # the log has gaps, and most rows have the target
        code, out, err = _run(
            capsys, ["fit", table, "--target", target, "--no-plots", "--json", "-"]
        )
        assert code == 0, err
        gaps = json.loads(out)["gaps"]
        assert gaps["missing"]["missing"] == empty.sum() and gaps["rows"] == len(empty)
        spikes = json.loads(out)["spikes"]
        flagged = spikes["flagged"] if spikes else 0
        assert gaps["used"] == len(empty) - empty.sum() - flagged
        stretches = gaps["missing"]["stretches"]
        assert sum(s["rows"] for s in stretches) == empty.sum()
        a, b = _longest_run(t, empty)
        longest = max(stretches, key=lambda s: s["rows"])
        assert longest["start_s"] / 60 == pytest.approx(a, abs=1e-6)
        assert longest["end_s"] / 60 == pytest.approx(b, abs=1e-6)
        line = next(ln for ln in err.splitlines() if ln.startswith("gaps: "))
        assert line.startswith(f"gaps: {empty.sum():,} of {len(empty):,} rows have no ")
        assert "filled" not in err.replace("never a filled", "")  # a target is never filled
    code, _, err = _run(
        capsys, ["grid", table, "--target", "current_speed", "-o", tmp_path / "maps.nc", "--quiet"]
    )
    assert code == 0, err
    t, empty = _empty(table, ["current_east", "current_north"])
    assert f"note: current_speed: {empty.sum():,} of {len(empty):,} rows have no current" in err
    assert (tmp_path / "maps.nc").stat().st_size > 0


@pytest.mark.slow
def test_diagnose_of_a_real_log_with_gaps_says_what_it_left_out(fjord, capsys, tmp_path):
    # once: "current east component has 6% missing values", exit 2
    table = tmp_path / fjord.name
    table.write_bytes(fjord.read_bytes())
    code, out, err = _run(
        capsys, ["diagnose", table, "--target", "current_speed", "--json", "-", "--rounds", "1"]
    )
    assert code == 0, err
    d = json.loads(out)
    t, empty = _empty(table, ["current_east", "current_north"])
    gaps = [f for f in d["data_quality"] if f["kind"] == "gaps"]
    assert len(gaps) == 1
    assert gaps[0]["text"].startswith(f"{empty.sum():,} of {len(empty):,} rows have no current")
    assert f"the other {len(empty) - empty.sum():,}" in gaps[0]["text"]
    assert len(d["candidates"]) >= 10  # the diagnosis ran over the candidates, gaps or not
    # time is judged where the race comes back, and the JSON says by how many pairs and on how many crossings
    v = next(c for c in d["candidates"] if c["covariate"] == "t")["time"]
    assert v["pairs"] > 50 and 1.0 <= v["evidence_crossings"] <= v["crossings"], v
    assert all(v["start_s"] <= s <= v["start_s"] + v["span_s"] for s in v["evidence_at_s"]), v
    assert v["unit"] == "m/s", v  # a current's east and north components


@pytest.mark.slow
def test_the_api_on_a_real_log_says_what_it_left_out(fjord):
    import forcemap

    survey = forcemap.read_survey(fjord)
    t, empty = _empty(fjord, ["depth"])
    fit = survey.fit("depth")
    assert fit.left_out[0].startswith(f"{empty.sum():,} of {len(empty):,} rows have no depth")
    a, b = _longest_run(t, empty)  # the longest silence of the sounder is named by its minutes
    assert f"{a:.1f} min" in fit.left_out[0] or f"{a:.0f}-{b:.0f} min" in fit.left_out[0]
    flagged = fit.model_.spikes.count if fit.model_.spikes else 0
    assert fit.n_rows == len(empty) - empty.sum() - flagged
    assert np.isfinite(fit.model_.measured).all() and np.isfinite(fit.cv_rmse)


# ---- a simulated survey with a known stretch blanked


@pytest.fixture(scope="module")
def river(tmp_path_factory) -> Path:
    return make_survey("river", ["depth_current"], 7, 900.0, tmp_path_factory.mktemp("river"))


def _blank(src: Path, dst: Path, column: str, keep) -> tuple[Path, int]:
    """A copy of the table with `column` emptied where `keep(t, i)` is false; the count emptied."""
    header, rows = csv_rows(src)
    i, t0 = header.index(column), float(rows[0][header.index("t")])
    n = 0
    for k, r in enumerate(rows):
        if not keep(float(r[header.index("t")]) - t0, k):
            r[i], n = "", n + 1
    return write_csv_rows(dst, header, rows), n


def test_a_known_stretch_without_depth_is_named_by_its_times(river, tmp_path, capsys):
    table, n = _blank(river, tmp_path / "s.csv", "depth", lambda t, k: not 300.0 <= t < 420.0)
    assert n == 120
    code, out, err = _run(capsys, ["fit", table, "--target", "depth", "--no-plots", "--json", "-"])
    assert code == 0, err
    line = next(ln for ln in err.splitlines() if ln.startswith("gaps: "))
    assert re.search(r"120 of 900 rows have no depth \(5-7 min into the survey\)", line), line
    assert "the map uses the other 780" in line
    stretch = json.loads(out)["gaps"]["missing"]["stretches"]
    assert len(stretch) == 1 and stretch[0]["rows"] == 120
    assert stretch[0]["start_s"] == pytest.approx(300.0, abs=1.0)
    assert stretch[0]["end_s"] == pytest.approx(419.0, abs=1.0)


def test_the_plans_maps_use_the_rows_that_have_the_current(river, tmp_path):
    from forcemap.host.plan.maps import survey_maps

    # one component lost is the vector lost: both are needed on a row
    table, n = _blank(
        river, tmp_path / "p.csv", "current_east", lambda t, k: not 200.0 <= t < 320.0
    )
    survey = load_survey(table)
    lo, hi = survey.xy.min(axis=0), survey.xy.max(axis=0)
    maps = survey_maps(table, survey, (lo[0], hi[0], lo[1], hi[1]), progress=False)
    said = [x for x in maps.notes if x.startswith("current: ")]
    assert any(x.startswith(f"current: {n} of 900 rows have no current (3-5 min") for x in said), (
        said
    )
    assert np.isfinite(maps.current.east).all() and np.isfinite(maps.current.north).all()
    assert survey.n == 900  # the table keeps every row: a row without current still has its depth


def test_ten_rows_of_a_target_are_too_few_and_say_so(river, tmp_path, capsys):
    table, n = _blank(river, tmp_path / "ten.csv", "depth", lambda t, k: k % 90 == 0)
    assert n == 890
    code, _, err = _run(capsys, ["fit", table, "--target", "depth", "--quiet"])
    assert code == 2
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("note:")]
    assert lines == ["forcemap fit: only 10 rows have depth; a map needs at least 30"], err
    # the other targets of the table are untouched: its current is still mapped
    code, _, err = _run(
        capsys, ["fit", table, "--target", "current_speed", "--no-plots", "--quiet"]
    )
    assert code == 0, err


def test_correlation_time_is_the_lag_where_the_autocorrelation_falls_to_1_over_e():
    # an AR(1) series sampled at 1 Hz with a known correlation time of 20 s
    rng = np.random.default_rng(1)
    tau, n = 20.0, 20000
    phi = np.exp(-1.0 / tau)
    x = np.zeros(n)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + rng.normal()
    t = np.arange(n, dtype=float)
    assert correlation_time(t, x) == pytest.approx(tau, rel=0.15)
    x[5000:5100] = np.nan  # gaps do not change it
    assert correlation_time(t, x) == pytest.approx(tau, rel=0.15)
    # an angle through its unit vector: a heading wandering across north is not decorrelated by the wrap
    heading = (np.degrees(np.cumsum(rng.normal(0.0, 0.02, n))) + 360.0) % 360.0
    assert correlation_time(t, heading, circular=True) > 100.0


@pytest.mark.slow
def test_diagnose_judges_a_covariate_with_a_long_gap_on_the_rows_that_have_it(
    river, tmp_path, capsys
):
    # depth is the current's missing effect; the sounder is silent for three minutes and skips single
    # pings: the long gap leaves its rows out of depth's judgement, the single pings are bridged
    def keep(t, k):
        return not (300.0 <= t < 480.0) and k % 25 != 3

    table, n = _blank(river, tmp_path / "d.csv", "depth", keep)
    single = sum(1 for k in range(900) if k % 25 == 3 and not 300 <= k < 480)
    code, out, err = _run(
        capsys, ["diagnose", table, "--target", "current_speed", "--json", "-", "--rounds", "1"]
    )
    assert code == 0, err
    d = json.loads(out)
    depth = next(c for c in d["candidates"] if c["covariate"] == "depth")
    assert d["missing_effect_found"] and d["candidates"][0]["covariate"] == "depth", depth
    code, out, _ = _run(capsys, ["fit", table, "--target", "current_speed", "--json", "-"])
    base = json.loads(out)["gaps"]["used"]  # the current model's rows: every row has current
    assert base == 900 - (json.loads(out)["spikes"] or {"flagged": 0})["flagged"]
    assert depth["rows"] == base - 180  # the three minutes without a sounding, and only them
    assert f"covariate 'depth': {single} missing value(s)" in err  # the single pings, bridged


@pytest.mark.slow
@pytest.mark.parametrize("n_basis", [40, 120])  # the dense products, and the NUFFT tables (fourier.is_fast)
def test_season_keeps_the_depth_of_rows_without_current(tmp_path, n_basis):
    paths = make_season(3, 10, tmp_path / "season", samples=1200, seed=2)
    table = pq.read_table(paths[1]).to_pandas()
    gone = (table.index >= 300) & (table.index < 500)  # the speed log silent on 200 rows
    for c in [c for c in table.columns if c.startswith("current_")]:
        table.loc[gone, c] = np.nan
    table.to_parquet(paths[1])
    season = run_season(paths, LocalRunner(), n_basis=n_basis, cv=True)
    assert not season.rejected
    assert fourier.is_fast(season.frame.space) == (n_basis == 120)
    one = next(s for s in season.surveys if s.path == str(paths[1]))
    n = len(table)
    assert one.stats["current"].n == n - 200  # the current from the rows that have it
    assert one.stats["depth"].n == n  # and every row's depth, those without current too
    assert any(note.startswith(f"200 of {n:,} rows have no current") for note in one.notes)
    assert season.current is not None and len(season.current.scales) == 3
    # exactly the statistics of the rows that have the current, as if the others were never logged
    s = load_survey(paths[1])
    ok = np.isfinite(s.columns["current_east"]) & np.isfinite(s.columns["current_north"])
    Y = np.column_stack([s.columns["current_east"], s.columns["current_north"]])[ok]
    Z = season.frame.xy(s.columns["lat"], s.columns["lon"])[ok]
    Phi = season.frame.space_features(Z)  # the plain products, whichever path the season took
    ref = {"G": Phi.T @ Phi, "B": Phi.T @ Y, "R": Y.T @ Y}
    for m in ("G", "B", "R"):
        a, b = getattr(one.stats["current"], m), ref[m]
        assert np.max(np.abs(a - b)) <= 1e-9 * np.max(np.abs(b)), m
