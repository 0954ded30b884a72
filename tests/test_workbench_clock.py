"""Finding and undoing a clock offset between the autopilot and the bridge (host.workbench.terms.clock_offset).

The table here is built from first principles: a steady wind, a boat that runs straight legs and turns at
25 deg/s between them, the anemometer's reading in the boat frame, and the daemon's true-wind sum made with
the autopilot's heading and velocity from `lag` seconds earlier.
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import is_circular, load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms import clock_offset
from forcemap.host.workbench.validation.cv import blocked_folds

RATE_HZ = 4.0
WIND = np.array([-4.0, -3.0])  # air velocity (east, north), m/s: a 5 m/s wind from 53 deg
LAT0, LON0 = 47.0, 8.0


def _track(duration_s: float, seed: int) -> dict[str, np.ndarray]:
    """Legs of 40 s at 2 m/s joined by 180-degree turns at 25 deg/s, turning each way in turn."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / RATE_HZ)
    rate = np.zeros_like(t)
    turn_s, leg_s = 180.0 / 25.0, 40.0
    sign, start = 1.0, leg_s
    while start < duration_s:
        rate[(t >= start) & (t < start + turn_s)] = 25.0 * sign
        sign, start = -sign, start + turn_s + leg_s
    heading = (20.0 + np.cumsum(rate) / RATE_HZ) % 360.0
    h = np.radians(heading)
    v = 2.0 * np.column_stack([np.sin(h), np.cos(h)])
    xy = np.cumsum(v, axis=0) / RATE_HZ
    wind = WIND + 0.3 * rng.standard_normal((len(t), 2))
    return {"t": t, "heading": heading, "v": v, "xy": xy, "wind": wind}


def _lagged(a: np.ndarray, n: int) -> np.ndarray:
    return a if n == 0 else np.concatenate([np.repeat(a[:1], n, axis=0), a[:-n]])


def make_table(path: Path, lag_s: float, seed: int = 1, duration_s: float = 900.0) -> Path:
    """The daemon's table when the autopilot's data reach it `lag_s` late."""
    k = _track(duration_s, seed)
    n = int(round(lag_s * RATE_HZ))
    h_used = _lagged(k["heading"], n)
    v_used = _lagged(k["v"], n)
    # the air relative to the boat, in the world, turned into the boat frame by the true heading and back
    # out by the heading the daemon has: a rotation by (used - true)
    rel = k["wind"] - k["v"]
    d = np.radians(h_used - k["heading"])
    cd, sd = np.cos(d), np.sin(d)
    w = np.column_stack([rel[:, 0] * cd + rel[:, 1] * sd, -rel[:, 0] * sd + rel[:, 1] * cd])
    w = w + v_used
    lat, lon = LocalFrame(LAT0, LON0).to_latlon(k["xy"][:, 0], k["xy"][:, 1])
    cols = {
        "t": 1.7e9 + k["t"],
        "lat": lat,
        "lon": lon,
        "heading": h_used,
        "sog": np.hypot(v_used[:, 0], v_used[:, 1]),
        "cog": np.degrees(np.arctan2(v_used[:, 0], v_used[:, 1])) % 360.0,
        "wind_east": w[:, 0],
        "wind_north": w[:, 1],
        "wind_speed": np.hypot(w[:, 0], w[:, 1]),
        "wind_dir": np.degrees(np.arctan2(-w[:, 0], -w[:, 1])) % 360.0,
        "depth": 3.0 + 0.01 * k["xy"][:, 0],
    }
    with path.open("w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(cols)
        wr.writerows(zip(*cols.values(), strict=True))
    return path


@pytest.fixture(scope="module")
def late(tmp_path_factory) -> Path:
    return make_table(tmp_path_factory.mktemp("clock") / "late.csv", 1.5)


@pytest.fixture(scope="module")
def on_time(tmp_path_factory) -> Path:
    return make_table(tmp_path_factory.mktemp("clock") / "on_time.csv", 0.0)


def test_no_shift_reproduces_the_table(late):
    s = load_survey(late)
    vt = s.vector_target("wind_dir")
    e, n = clock_offset.shifted_vector(s, vt, 0.0)
    assert np.allclose(e, s.columns["wind_east"], atol=1e-9)
    assert np.allclose(n, s.columns["wind_north"], atol=1e-9)


@pytest.mark.parametrize(("lag", "table"), [(1.5, "late"), (0.0, "on_time")])
def test_the_scan_finds_the_offset(lag, table, request):
    s = load_survey(request.getfixturevalue(table))
    scan = clock_offset.scan_offset(s, s.vector_target("wind_speed"))
    assert scan.offset_s == pytest.approx(lag, abs=0.1)
    if lag:
        assert scan.reduction > 0.3
    else:
        assert scan.reduction < 0.01


def test_the_corrected_wind_is_the_true_wind(late):
    s = load_survey(late)
    vt = s.vector_target("wind_speed")
    corrected, tau = clock_offset.corrected_for(s, vt, math.nan)
    err_before = np.hypot(s.columns["wind_east"] - WIND[0], s.columns["wind_north"] - WIND[1])
    c = corrected.columns
    err_after = np.hypot(c["wind_east"] - WIND[0], c["wind_north"] - WIND[1])
    # the sensor noise (0.3 m/s per component) stays; the swing in the turns goes
    assert np.sqrt(np.mean(err_before**2)) > 2.0 * np.sqrt(np.mean(err_after**2))
    assert np.sqrt(np.mean(err_after**2)) < 0.6
    assert np.allclose(c["wind_speed"], np.hypot(c["wind_east"], c["wind_north"]))
    assert tau == pytest.approx(1.5, abs=0.1)


def test_the_offset_is_an_ordinary_term():
    """Parsed by the registry like any term; it acts on the survey before the model, not as a sum term."""
    from forcemap.host.workbench.terms import registry

    def spec(text):
        return registry.parse_term(text, is_circular)

    model, data = registry.split_data_terms([spec("const"), spec("clock_offset")])
    assert [str(s) for s in model] == ["const"] and [str(s) for s in data] == ["clock_offset"]
    assert math.isnan(registry.build_term(spec("clock_offset"), is_circular).tau)
    assert registry.build_term(spec("clock_offset(+1.50 s)"), is_circular).tau == 1.5
    assert str(spec("clock_offset(-0.4)")) == "clock_offset(-0.40 s)"
    assert registry.corrections(["gp(t, matern32)", "const"], is_circular) == []
    with pytest.raises(WorkbenchError):
        spec("clock_offset(soon)")


def test_a_model_with_the_offset_names_it_and_fits_better(late):
    s = load_survey(late)
    base = SurveyModel(s, "wind_dir").fit()
    fixed = SurveyModel(s, "wind_dir", ["const", "gp(position, matern32)", "clock_offset"]).fit()
    assert re.fullmatch(r"clock_offset\(\+1\.[45]\d s\)", fixed.terms[-1]), fixed.terms
    folds = blocked_folds(s.xy, 5, 0)[0]
    assert fixed.cv(folds).rmse < 0.5 * base.cv(folds).rmse
    # a fixed value is used as given
    given = SurveyModel(s, "wind_dir", ["clock_offset(+0.75 s)"])
    assert given.terms[-1] == "clock_offset(+0.75 s)"


def test_only_vectors_take_an_offset(late):
    with pytest.raises(WorkbenchError, match="applies to wind and current"):
        SurveyModel(load_survey(late), "depth", ["clock_offset"])


def test_diagnose_then_fit_from_the_command_line(late, tmp_path, capsys):
    dj = tmp_path / "diag.json"
    diag = ["diagnose", str(late), "--target", "wind_dir", "--json", str(dj)]
    assert main(diag) == 0
    d = json.loads(dj.read_text())
    assert d["missing_effect_found"] and d["candidates"][0]["covariate"] == "clock_offset"
    assert "clock offset" in d["candidates"][0]["explanation"]
    out = tmp_path / "fit.json"
    args = ["fit", str(late), "--target", "wind_dir", "--quiet", "--json", str(out)]
    assert main(args) == 0
    base = json.loads(out.read_text())
    assert main(args + ["--effects", "clock_offset", "--force"]) == 0  # replaces fit.json
    fixed = json.loads(out.read_text())
    assert fixed["terms"][-1].startswith("clock_offset(+1.")
    assert fixed["cv_rmse"] < 0.5 * base["cv_rmse"]
    # the report's wind map uses the offset found for the direction: it corrects the whole vector
    html_out = tmp_path / "report.html"
    assert main(["report", str(late), "-o", str(html_out), "--quiet"]) == 0
    assert re.search(
        r"wind: const \+ gp\(position, matern32\) \+ clock_offset\(\+1\.", html_out.read_text()
    )
    # diagnose starts from the survey's latest fit, which now undoes the offset: nothing is left
    assert main([*diag, "--force"]) == 0
    d = json.loads(dj.read_text())
    assert d["baseline"]["terms"][-1].startswith("clock_offset(+1.")
    assert not d["missing_effect_found"]
    assert "clock_offset" not in [c["covariate"] for c in d["candidates"]]
    capsys.readouterr()


def test_no_offset_is_not_reported(on_time, tmp_path):
    dj = tmp_path / "diag.json"
    assert main(["diagnose", str(on_time), "--target", "wind_dir", "--json", str(dj)]) == 0
    d = json.loads(dj.read_text())
    assert not d["missing_effect_found"]
    c = next(c for c in d["candidates"] if c["covariate"] == "clock_offset")
    assert abs(c["improvement"]) < 0.05


def _with_gaps(src: Path, dst: Path, column: str, every: int) -> Path:
    with src.open() as f:
        rows = list(csv.reader(f))
    i = rows[0].index(column)
    for r in rows[1::every]:
        r[i] = ""
    with dst.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    return dst


def test_gaps_in_the_heading_are_filled(late, tmp_path):
    s = load_survey(_with_gaps(late, tmp_path / "gaps.csv", "heading", 40))
    assert clock_offset.scan_offset(s, s.vector_target("wind_dir")).offset_s == pytest.approx(
        1.5, abs=0.1
    )
    assert any("heading" in n for n in s.notes)


def test_a_heading_read_at_half_the_rate_is_bridged(late, tmp_path, capsys):
    # once refused ("50% missing values"): one row in two without a heading is a heading read at half
    # the rate, every gap far shorter than its correlation time; no row is lost
    table = _with_gaps(late, tmp_path / "holes.csv", "heading", 2)
    n = sum(1 for _ in table.open()) - 1
    args = ["fit", str(table), "--target", "wind_dir", "--effects", "clock_offset", "--json", "-"]
    assert main([*args, "--no-plots"]) == 0
    out, err = capsys.readouterr()
    assert f"covariate 'heading': {n // 2} missing value(s) in {n // 2} gap(s)" in err
    assert json.loads(out)["gaps"]["used"] == n
    assert re.search(r"clock_offset\(\+1\.[4-6]\d s\)", " ".join(json.loads(out)["terms"]))


def test_a_heading_lost_for_minutes_leaves_those_rows_out(late, tmp_path, capsys):
    with late.open() as f:
        rows = list(csv.reader(f))
    i, t0 = rows[0].index("heading"), float(rows[1][0])
    lost = [r for r in rows[1:] if 120.0 <= float(r[0]) - t0 < 360.0]
    for r in lost:
        r[i] = ""
    table = tmp_path / "lost.csv"
    with table.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    args = ["fit", str(table), "--target", "wind_dir", "--effects", "clock_offset", "--json", "-"]
    assert main([*args, "--no-plots"]) == 0
    out, err = capsys.readouterr()
    gaps = json.loads(out)["gaps"]
    # the four minutes without a heading, and only they, are left out of the model that needs it
    assert gaps["covariates"]["heading"]["missing"] == len(lost)
    assert gaps["used"] == len(rows) - 1 - len(lost)
    assert re.search(r"have no heading for longer than its correlation time \(2-6 min", err), err
    # with a heading on a few seconds only, too little is left, said in one line with the count
    for r in rows[12:]:
        r[i] = ""
    with table.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    assert main([*args[:-2], "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [ln for ln in err.strip().splitlines() if ln.startswith("forcemap")]
    assert len(lines) == 1 and re.search(r"only \d+ rows have wind and heading", lines[0]), err
