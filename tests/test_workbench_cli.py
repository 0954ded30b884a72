"""Reading tables (CSV, Parquet, MCAP), clear one-line errors, and the fit/diagnose/history/report commands."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.workbench.survey.table import load_survey
from pyproj import Geod

from bench.synth_survey import make_survey
from tests.tools import csv_rows, write_csv_rows


@pytest.fixture(scope="module")
def survey_csv(tmp_path_factory) -> Path:
    return make_survey("river", ["depth_current"], 11, 1200.0, tmp_path_factory.mktemp("survey"))


def test_csv_parquet_and_mcap_read_the_same(survey_csv, tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq
    from mcap.writer import Writer

    s = load_survey(survey_csv)
    header, rows = csv_rows(survey_csv)
    cols = {h: [float(r[i]) for r in rows] for i, h in enumerate(header)}
    pq.write_table(pa.table(cols), tmp_path / "s.parquet")
    with (tmp_path / "s.mcap").open("wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema(name="sample", encoding="jsonschema", data=b"{}")
        cid = w.register_channel(topic="/samples", message_encoding="json", schema_id=sid)
        for i in range(len(rows)):
            msg = {h: cols[h][i] for h in header}
            ns = int(msg["t"] * 1e9)
            w.add_message(
                channel_id=cid, log_time=ns, publish_time=ns, data=json.dumps(msg).encode()
            )
        w.finish()
    for other in (tmp_path / "s.parquet", tmp_path / "s.mcap"):
        o = load_survey(other)
        assert o.n == s.n
        assert np.allclose(o.xy, s.xy)
        assert np.allclose(o.columns["current_speed"], s.columns["current_speed"])


def test_local_frame_is_metres_about_the_centre(survey_csv):
    s = load_survey(survey_csv)
    # the synthetic reach is 600 m x 150 m around its centre
    span = np.ptp(s.xy, axis=0)
    assert 500 < span[0] < 620 and 30 < span[1] < 160  # legs 570 m long, 15 m apart
    assert abs(s.xy[:, 0].min() + s.xy[:, 0].max()) < 1.0
    lat, lon = s.columns["lat"][0], s.columns["lon"][0]
    # north of the centre by the WGS-84 geodesic along the meridian
    _, _, dy = Geod(ellps="WGS84").inv(s.lon0, s.lat0, s.lon0, lat)
    assert abs(s.xy[0, 1]) == pytest.approx(dy, abs=0.01)
    assert s.xy[0, 1] * (lat - s.lat0) >= 0
    assert s.xy[0, 0] * (lon - s.lon0) >= 0


def _run(capsys, argv):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _one_line_error(code, err, pattern):
    assert code == 2
    assert "Traceback" not in err
    lines = [ln for ln in err.strip().splitlines() if ln.startswith("forcemap")]
    assert len(lines) == 1 and re.search(pattern, lines[0]), err


def test_unknown_target(survey_csv, capsys):
    code, _, err = _run(capsys, ["fit", str(survey_csv), "--target", "salinity", "--quiet"])
    _one_line_error(code, err, "unknown target 'salinity'")


def test_angle_target_is_refused(survey_csv, capsys):
    code, _, err = _run(capsys, ["fit", str(survey_csv), "--target", "heading", "--quiet"])
    _one_line_error(code, err, "angle")


def test_constant_target(survey_csv, tmp_path, capsys):
    header, rows = csv_rows(survey_csv)
    i = header.index("water_temp")
    for r in rows:
        r[i] = "18.0"
    p = write_csv_rows(tmp_path / "c.csv", header, rows)
    code, _, err = _run(capsys, ["fit", str(p), "--target", "water_temp", "--quiet"])
    _one_line_error(code, err, "constant")


def test_non_numeric_target(survey_csv, tmp_path, capsys):
    # a column of words is not numeric; one word in a column of numbers is a missing cell (test_bad_input)
    header, rows = csv_rows(survey_csv)
    i = header.index("depth")
    for r in rows:
        r[i] = "deep"
    p = write_csv_rows(tmp_path / "n.csv", header, rows)
    code, _, err = _run(capsys, ["fit", str(p), "--target", "depth", "--quiet"])
    _one_line_error(code, err, "not numeric")


def test_a_target_missing_on_every_third_row_is_fitted_on_the_rest(survey_csv, tmp_path, capsys):
    # once refused ("33% missing values"): the rows that have depth are mapped, none is filled in
    header, rows = csv_rows(survey_csv)
    i = header.index("depth")
    for r in rows[::3]:
        r[i] = ""
    p = write_csv_rows(tmp_path / "m.csv", header, rows)
    argv = ["fit", str(p), "--target", "depth", "--no-plots", "--json", "-"]
    code, out, err = _run(capsys, argv)
    assert code == 0, err
    fit = json.loads(out)
    blank = len(rows[::3])
    assert fit["gaps"]["missing"]["missing"] == blank and fit["gaps"]["rows"] == len(rows)
    spikes = fit["spikes"]["flagged"] if fit["spikes"] else 0
    assert fit["gaps"]["used"] == len(rows) - blank - spikes
    assert f"{blank} of {len(rows):,} rows have no depth" in err
    assert "filled" not in err  # a target is never filled from its neighbours


def test_too_fewcsv_rows(survey_csv, tmp_path, capsys):
    header, rows = csv_rows(survey_csv)
    p = write_csv_rows(tmp_path / "few.csv", header, rows[:10])
    code, _, err = _run(capsys, ["fit", str(p), "--target", "depth", "--quiet"])
    _one_line_error(code, err, "only 10 usable rows")


def test_missing_position_column(survey_csv, tmp_path, capsys):
    header, rows = csv_rows(survey_csv)
    i = header.index("lat")
    p = write_csv_rows(
        tmp_path / "nolat.csv", header[:i] + header[i + 1 :], [r[:i] + r[i + 1 :] for r in rows]
    )
    code, _, err = _run(capsys, ["fit", str(p), "--target", "depth", "--quiet"])
    _one_line_error(code, err, "required column")


def test_fit_history_report(survey_csv, tmp_path, capsys):
    table = tmp_path / "survey.csv"
    table.write_bytes(survey_csv.read_bytes())
    out_json = tmp_path / "fit.json"
    code, out, _ = _run(
        capsys, ["fit", str(table), "--target", "current_speed", "--json", str(out_json), "--quiet"]
    )
    assert code == 0
    base = json.loads(out_json.read_text())
    assert set(base) == {
        "target", "terms", "cv_rmse", "cv_mae", "coverage95", "calibration", "spikes", "gaps",
        "crossline_rmse", "crossline_samples",
    }  # fmt: skip
    # where the lawnmower's turns revisit its lines, each time stretch held out: a real error, on real rows
    assert base["crossline_samples"] > 0 and 0.0 < base["crossline_rmse"] < 10 * base["cv_rmse"]
    assert set(base["calibration"]) == {"sd_scale", "model_coverage", "coverage", "reach_m"}
    assert base["target"] == "current_speed" and base["terms"] == [
        "const",
        "gp(position, matern32)",
    ]
    assert 0.0 <= base["coverage95"] <= 1.0 and base["cv_mae"] <= base["cv_rmse"]
    assert "where the model fails most" in out
    code, _, _ = _run(
        capsys,
        [
            "fit",
            str(table),
            "--target",
            "current_speed",
            "--effects",
            "depth",
            "--json",
            str(out_json),
            "--force",
            "--quiet",
        ],
    )
    assert code == 0
    with_depth = json.loads(out_json.read_text())
    assert with_depth["terms"][-1] == "gp(depth, matern32)"
    assert with_depth["cv_rmse"] < 0.7 * base["cv_rmse"]
    code, out, _ = _run(capsys, ["history", str(table)])
    assert code == 0
    assert len([ln for ln in out.splitlines() if re.match(r"\s+\d+\s+\d{4}-", ln)]) == 2
    assert (tmp_path / "survey.csv.forcemap" / "history.png").stat().st_size > 1000
    report = tmp_path / "r.html"
    code, _, _ = _run(capsys, ["report", str(table), "-o", str(report), "--quiet"])
    assert code == 0
    text = report.read_text()
    assert text.count("data:image/png;base64,") >= 6
    assert not re.search(r"""src=["']https?:""", text)
    assert "Error history" in text and "gp(depth, matern32)" in text


def test_direction_target_is_modelled_through_components(survey_csv):
    from forcemap.host.workbench.fits.fit import fit_target

    s = load_survey(survey_csv)
    r = fit_target(s, "current_dir", ["const", "gp(position, matern32)"], progress=False)
    assert r.model.secondary is not None  # along/across-flow components, not a scalar angle
    assert r.cv.circular
    assert 0 < r.cv.rmse < 30  # degrees, wrapped
    assert 0.5 < r.cv.coverage95 <= 1.0


def test_diagnose_json_contract(survey_csv, tmp_path, capsys):
    table = tmp_path / "survey.csv"
    table.write_bytes(survey_csv.read_bytes())
    out_json = tmp_path / "d.json"
    code, out, _ = _run(
        capsys,
        ["diagnose", str(table), "--target", "current_speed", "--json", str(out_json), "--quiet"],
    )
    assert code == 0
    d = json.loads(out_json.read_text())
    assert set(d) == {
        "target",
        "baseline",
        "missing_effect_found",
        "candidates",
        "advice",
        "data_quality",
        "rounds",
    }
    assert set(d["baseline"]) == {"terms", "cv_rmse"}
    keys = {"covariate", "cv_rmse", "improvement", "explanation"}
    keys |= {"identifiable", "confounded_with", "null_gains", "rows", "time"}
    keys |= {"improvement_sd", "p_value", "credited", "why"}
    assert d["candidates"] and all(set(c) == keys for c in d["candidates"])
    # one scale: each effect with its sd, the verdict and what decided it
    assert all(c["why"] and c["improvement_sd"] >= 0 for c in d["candidates"])
    best = d["candidates"][0]
    assert best["credited"] and best["p_value"] <= d["rounds"][0]["threshold"]
    assert 0 < best["improvement_sd"] < best["improvement"]
    assert all(c["time"] is None for c in d["candidates"] if c["covariate"] != "t")  # the revisits judge t
    assert d["rounds"][0]["candidates"] == d["candidates"]
    assert d["rounds"][0]["added"] == ("gp(depth, matern32)" if d["missing_effect_found"] else None)
    gains = [c["improvement"] for c in d["candidates"]]
    assert gains[1:] == sorted(gains[1:], reverse=True)
    assert d["missing_effect_found"] is True and d["candidates"][0]["covariate"] == "depth"
    assert "continuity" in d["candidates"][0]["explanation"]


def test_help_teaches_with_examples(capsys):
    with pytest.raises(SystemExit):
        main(["fit", "--help"])
    out = capsys.readouterr().out
    assert "examples:" in out and "--effects depth" in out


def test_model_spec_toml_with_user_term_and_random_folds(survey_csv, tmp_path, capsys, monkeypatch):
    (tmp_path / "mylaws2.py").write_text(
        "def manning(depth, k=1.0):\n    return k * depth ** (2.0 / 3.0)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    spec = tmp_path / "spec.toml"
    spec.write_text(
        'target = "current_speed"\n'
        'terms = ["const", "gp(position, matern32)"]\n'
        '[[term]]\nkind = "user"\ninputs = ["depth"]\nfunction = "mylaws2:manning"\n'
    )
    table = tmp_path / "survey.csv"
    table.write_bytes(survey_csv.read_bytes())
    out = tmp_path / "f.json"
    code, text, _ = _run(
        capsys,
        ["fit", str(table), "--model", str(spec), "--json", str(out), "--quiet", "--no-plots"],
    )
    assert code == 0, text
    blocked = json.loads(out.read_text())
    assert blocked["terms"] == ["const", "gp(position, matern32)", "user(depth, mylaws2:manning)"]
    assert "user(depth, mylaws2:manning): k=" in text
    code, text, _ = _run(
        capsys,
        [
            "fit",
            str(table),
            "--model",
            str(spec),
            "--folds",
            "random",
            "--json",
            str(out),
            "--force",
            "--quiet",
            "--no-plots",
        ],
    )
    assert code == 0
    # random folds keep each held-out sample's along-track neighbours in training: they flatter the model
    assert json.loads(out.read_text())["cv_rmse"] < blocked["cv_rmse"]
    assert "flatter" in text


def test_rows_without_position_are_dropped_with_a_note(survey_csv, tmp_path, capsys):
    # a GPS outage leaves a stretch of samples with no position: they are dropped, the rest is fitted
    header, rows = csv_rows(survey_csv)
    i, j = header.index("lat"), header.index("lon")
    n = len(rows)
    for r in rows[n // 3 : n // 3 + n // 5]:
        r[i] = r[j] = ""
    p = write_csv_rows(tmp_path / "gps-outage.csv", header, rows)
    code, _, err = _run(capsys, ["fit", str(p), "--target", "depth", "--no-plots"])
    assert code == 0, err
    assert "dropped" in err and "'lat'" in err


def test_table_mostly_without_position_is_refused(survey_csv, tmp_path, capsys):
    header, rows = csv_rows(survey_csv)
    i = header.index("lat")
    for r in rows[: 2 * len(rows) // 3]:
        r[i] = ""
    p = write_csv_rows(tmp_path / "no-gps.csv", header, rows)
    code, _, err = _run(capsys, ["fit", str(p), "--target", "depth", "--quiet"])
    _one_line_error(code, err, "missing values")
