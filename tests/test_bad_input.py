"""Every command under bad input: one clear line and exit 2, or a counted note; nothing lost, nothing silent.

One test (or more) per row of docs/BAD_INPUT.md for the workbench commands (fit, diagnose, history,
report). The checks that come before a fit are shown to come before it: the workspace gets no fit and no
progress line is printed.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.fits.workspace import record_fit, workspace_dir
from forcemap.host.workbench.survey.table import load_survey

from bench.synth_survey import LAT0, LON0, make_survey
from tests.tools import csv_rows, write_csv_rows


@pytest.fixture(scope="module")
def small_csv(tmp_path_factory) -> Path:
    """400 s of the synthetic river: enough rows to fit in seconds."""
    return make_survey("river", ["depth_current"], 5, 400.0, tmp_path_factory.mktemp("small"))


def _copy(src: Path, dst: Path) -> Path:
    dst.write_bytes(src.read_bytes())
    return dst


def _run(capsys, argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _one_line(code, err, *patterns):
    """Exit 2, no traceback, one `forcemap CMD:` line matching every pattern, and nothing else."""
    assert code == 2, err
    assert "Traceback" not in err
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("note:")]
    assert len(lines) == 1 and lines[0].startswith("forcemap "), err
    for p in patterns:
        assert re.search(p, lines[0]), (p, lines[0])
    return lines[0]


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# --- the workspace is never silently reset -------------------------------------------------------


def test_corrupt_history_stops_the_fit_and_reset_keeps_a_backup(small_csv, tmp_path, capsys):
    table = _copy(small_csv, tmp_path / "survey.csv")
    code, _, err = _run(
        capsys, ["fit", table, "--target", "current_speed", "--quiet", "--no-plots"]
    )
    assert code == 0, err
    ws = tmp_path / "survey.csv.forcemap"
    first_model = ws / "models" / "fit-001-current_speed.json"
    model_bytes = first_model.read_bytes()
    history = ws / "history.json"
    # a hand edit leaves a trailing comma
    corrupt = history.read_text().rstrip().rstrip("]").rstrip() + ",\n]"
    history.write_text(corrupt)
    code, _, err = _run(capsys, ["fit", table, "--target", "current_speed", "--no-plots"])
    line = _one_line(code, err, re.escape(str(history)), "--reset-history", "corrupt")
    assert "fitting" not in err, line  # refused before the fit
    assert history.read_text() == corrupt and first_model.read_bytes() == model_bytes
    # every command that reads the history says the same
    for cmd in (["history", table], ["diagnose", table, "--target", "depth"], ["report", table]):
        code, _, err = _run(capsys, [*cmd, "--quiet"] if cmd[0] != "history" else cmd)
        _one_line(code, err, re.escape(str(history)), "--reset-history")
    # the way out: the old history is moved aside, never deleted, and fit-001 is never overwritten
    code, out, err = _run(
        capsys,
        ["fit", table, "--target", "current_speed", "--reset-history", "--quiet", "--no-plots"],
    )
    assert code == 0, err
    backup = ws / "history.json.bak-1"
    assert backup.read_text() == corrupt and "kept as" in err
    assert first_model.read_bytes() == model_bytes
    new = json.loads(history.read_text())
    assert [h["fit"] for h in new] == [2] and new[0][
        "model_file"
    ] == "models/fit-002-current_speed.json"
    assert "saved fit 2" in out


def test_history_that_is_not_a_list_of_fits_is_corrupt(small_csv, tmp_path, capsys):
    table = _copy(small_csv, tmp_path / "survey.csv")
    ws = workspace_dir(table)
    for text in ('{"fit": 1}', '[{"fit": "one", "target": 3}]', "\xff\xfe"):
        (ws / "history.json").write_bytes(text.encode("latin-1"))
        code, _, err = _run(capsys, ["history", table])
        _one_line(code, err, "history.json: the fit history is corrupt", "--reset-history")


def test_a_fit_never_overwrites_another_fits_files(tmp_path):
    ws = workspace_dir(tmp_path / "t.csv")
    entry = {
        "target": "depth",
        "terms": ["const"],
        "cv_rmse": 1.0,
        "cv_mae": 0.5,
        "coverage95": 0.9,
    }
    assert record_fit(ws, entry, {"theta": [1.0]})["fit"] == 1
    # the history is lost (deleted by hand); the next fit is numbered past the files that remain
    (ws / "history.json").unlink()
    (ws / "models" / "fit-007-wind_speed.json").write_text("{}")
    e = record_fit(ws, entry, {"theta": [2.0]})
    assert e["fit"] == 8 and e["model_file"] == "models/fit-008-depth.json"
    assert json.loads((ws / "models" / "fit-001-depth.json").read_text())["theta"] == [1.0]
    assert (ws / "models" / "fit-007-wind_speed.json").read_text() == "{}"


def test_a_fit_whose_cv_error_is_nan_is_never_saved(tmp_path):
    ws = workspace_dir(tmp_path / "t.csv")
    entry = {
        "target": "depth",
        "terms": ["const"],
        "cv_rmse": 1.0,
        "cv_mae": 0.5,
        "coverage95": 0.9,
    }
    record_fit(ws, entry, {})
    before = (ws / "history.json").read_bytes()
    with pytest.raises(WorkbenchError, match="not a number; the fit is not saved"):
        record_fit(ws, {**entry, "cv_rmse": math.nan}, {})
    assert (ws / "history.json").read_bytes() == before
    assert sorted(p.name for p in (ws / "models").iterdir()) == ["fit-001-depth.json"]


def test_workspace_that_cannot_be_created_is_one_line_before_the_fit(small_csv, tmp_path, capsys):
    # a read-only folder is found by os.access, which says yes to root (the tests may run as root):
    # here a file of the workspace's name is in the way, which no user can write through
    table = _copy(small_csv, tmp_path / "survey.csv")
    (tmp_path / "survey.csv.forcemap").write_text("not a folder")
    code, _, err = _run(capsys, ["fit", table, "--target", "depth"])
    _one_line(code, err, "survey.csv.forcemap is a file", "move it away")
    assert "fitting" not in err
    assert (tmp_path / "survey.csv.forcemap").read_text() == "not a folder"


# --- outputs are checked before the work, and never replaced without --force -----------------------


def test_outputs_into_a_missing_folder_are_refused_before_any_fitting(small_csv, tmp_path, capsys):
    table = _copy(small_csv, tmp_path / "survey.csv")
    missing = tmp_path / "no-such-folder"
    for argv in (
        ["fit", table, "--target", "depth", "--json", missing / "f.json"],
        ["diagnose", table, "--target", "depth", "--json", missing / "d.json"],
        ["report", table, "-o", missing / "r.html"],
    ):
        code, _, err = _run(capsys, argv)
        _one_line(code, err, f"the folder {re.escape(str(missing))} does not exist")
        assert "fitting" not in err and "cross-validating" not in err
    assert not (tmp_path / "survey.csv.forcemap").exists()  # refused commands leave nothing behind
    code, _, err = _run(capsys, ["fit", table, "--target", "depth", "--quiet", "--no-plots"])
    assert code == 0
    code, _, err = _run(capsys, ["history", table, "-o", missing / "h.png"])
    _one_line(code, err, "does not exist")
    assert not missing.exists()


def test_an_existing_output_is_replaced_only_with_force(small_csv, tmp_path, capsys):
    table = _copy(small_csv, tmp_path / "survey.csv")
    out = tmp_path / "mine.json"
    out.write_text("my notes\n")
    code, _, err = _run(capsys, ["fit", table, "--target", "depth", "--json", out, "--quiet"])
    _one_line(code, err, "exists; pass --force")
    assert out.read_text() == "my notes\n"
    code, _, err = _run(capsys, ["report", table, "-o", table, "--force", "--quiet"])
    _one_line(code, err, "also an input")
    assert _sha(table) == _sha(small_csv)
    code, _, err = _run(
        capsys,
        ["fit", table, "--target", "depth", "--json", out, "--force", "--quiet", "--no-plots"],
    )
    assert code == 0, err
    assert json.loads(out.read_text())["target"] == "depth"


# --- the table: nothing silently dropped, nothing silently wrong -----------------------------------


def test_a_cell_that_is_not_a_number_is_missing_and_named(small_csv, tmp_path, capsys):
    header, rows = csv_rows(small_csv)
    i = header.index("depth")
    rows[6][i] = "1,5"
    rows[40][i] = "deep"
    p = write_csv_rows(tmp_path / "comma.csv", header, rows)
    s = load_survey(p)
    assert "depth" in s.columns and "depth" not in s.non_numeric
    assert np.isnan(s.columns["depth"]).sum() == 2 and s.n == len(rows)
    note = next(n for n in s.notes if "not numbers" in n)
    assert "column 'depth': 2 cell(s)" in note and "7 '1,5'" in note and "decimal comma" in note
    code, out, err = _run(capsys, ["fit", p, "--target", "depth", "--quiet", "--no-plots"])
    assert code == 0 and "note: column 'depth': 2 cell(s) that are not numbers" in err


@pytest.mark.slow
def test_diagnose_still_finds_depth_with_one_bad_cell(tmp_path_factory, capsys):
    # the case: one `1,5` in the depth column once hid the depth effect ("no missing effect")
    src = make_survey("river", ["depth_current"], 11, 1200.0, tmp_path_factory.mktemp("big"))
    header, rows = csv_rows(src)
    rows[100][header.index("depth")] = "1,5"
    p = write_csv_rows(src.with_name("comma.csv"), header, rows)
    out = p.with_name("d.json")
    code, _, err = _run(
        capsys, ["diagnose", p, "--target", "current_speed", "--json", out, "--quiet"]
    )
    assert code == 0, err
    assert "'1,5'" in err
    d = json.loads(out.read_text())
    assert d["missing_effect_found"] and d["candidates"][0]["covariate"] == "depth"


def test_inf_is_missing_with_a_note(small_csv, tmp_path, capsys):
    header, rows = csv_rows(small_csv)
    i = header.index("water_temp")
    for r in rows[10:13]:
        r[i] = "inf"
    rows[20][i] = "-inf"
    s = load_survey(write_csv_rows(tmp_path / "inf.csv", header, rows))
    assert np.isnan(s.columns["water_temp"]).sum() == 4
    assert any("column 'water_temp': 4 infinite value(s) made missing" in n for n in s.notes)


@pytest.mark.parametrize("fill", ["inf", "", "nan", "-inf"])
@pytest.mark.parametrize("target", ["depth", "current_speed"])
def test_an_unusable_target_is_an_error_before_fitting(small_csv, tmp_path, capsys, fill, target):
    header, rows = csv_rows(small_csv)
    # a vector's speed is modelled through its components: all of them are made unusable
    dead = [target] if target == "depth" else [h for h in header if h.startswith("current_")]
    for r in rows:
        for c in dead:
            r[header.index(c)] = fill
    p = write_csv_rows(tmp_path / "dead.csv", header, rows)
    code, _, err = _run(capsys, ["fit", p, "--target", target, "--no-plots", "--quiet"])
    # the rows that have the target are fitted (a vector: both components); here there are none
    _one_line(code, err, "current|depth", "no row has")
    assert not (tmp_path / "dead.csv.forcemap" / "history.json").exists()
    # the same column as an effect
    code, _, err = _run(
        capsys, ["fit", p, "--target", "water_temp", "--effects", target, "--quiet"]
    )
    _one_line(code, err, target)


def test_lat_out_of_range_rows_are_dropped_with_a_note(small_csv, tmp_path):
    header, rows = csv_rows(small_csv)
    i = header.index("lat")
    for r in rows[50:53]:
        r[i] = "200"
    s = load_survey(write_csv_rows(tmp_path / "lat200.csv", header, rows))
    assert s.n == len(rows) - 3
    note = next(n for n in s.notes if "outside" in n)
    assert "dropped 3 row(s) with lat outside -90..90 (e.g. 200)" in note and "51, 52, 53" in note
    assert np.ptp(s.xy[:, 0]) < 1000 and np.ptp(s.xy[:, 1]) < 1000  # the reach, not 9,229 km


def test_lat_lon_swapped_in_some_rows_are_dropped_as_impossible_jumps(small_csv, tmp_path):
    header, rows = csv_rows(small_csv)
    i, j = header.index("lat"), header.index("lon")
    for r in rows[100:110]:
        r[i], r[j] = r[j], r[i]  # lat -81, lon 33.95: on the globe, 13,000 km away
    s = load_survey(write_csv_rows(tmp_path / "swap.csv", header, rows))
    assert s.n == len(rows) - 10
    note = next(n for n in s.notes if "jumps" in n)
    assert "dropped 10 row(s)" in note and "faster than 20 m/s" in note and "101, 102, 103" in note
    assert np.ptp(s.xy[:, 0]) < 1000
    # one glitch at the very first fix does not drag the track away with it
    header, rows = csv_rows(small_csv)
    rows[0][i], rows[0][j] = "0", "0"
    s = load_survey(write_csv_rows(tmp_path / "null-island.csv", header, rows))
    assert s.n == len(rows) - 1 and abs(s.lat0 - LAT0) < 0.01 and abs(s.lon0 - LON0) < 0.01


def test_lat_lon_swapped_everywhere_is_an_error(small_csv, tmp_path, capsys):
    header, rows = csv_rows(small_csv)
    i, j = header.index("lat"), header.index("lon")
    header[i], header[j] = header[j], header[i]  # lat = -81.05 is on the globe; lon = 33.95 too ...
    p = write_csv_rows(tmp_path / "swapped.csv", header, rows)
    s = load_survey(p)  # ... so the map is a consistent one, only mirrored: metres, not megametres
    assert np.ptp(s.xy[:, 0]) < 1000 and np.ptp(s.xy[:, 1]) < 1000
    # a place where swapping leaves the globe: lon 120 E becomes lat 120
    header, rows = csv_rows(small_csv)
    for r in rows:
        r[i], r[j] = f"{float(r[j]) + 201.05:.7f}", r[i]
    code, _, err = _run(
        capsys, ["fit", write_csv_rows(tmp_path / "asia.csv", header, rows), "--target", "depth"]
    )
    _one_line(code, err, "lat outside -90..90", "are lat and lon swapped")


def test_a_folder_non_utf8_and_bom(small_csv, tmp_path, capsys):
    code, _, err = _run(capsys, ["fit", tmp_path, "--target", "depth"])
    _one_line(code, err, "is a folder")
    latin = tmp_path / "latin1.csv"
    latin.write_bytes(small_csv.read_bytes().replace(b"water_temp", b"temp\xe9rature", 1))
    code, _, err = _run(capsys, ["fit", latin, "--target", "depth"])
    _one_line(code, err, "not UTF-8 text", "CSV UTF-8")
    binary = tmp_path / "run.csv"
    binary.write_bytes(bytes(range(256)) * 4)
    code, _, err = _run(capsys, ["diagnose", binary, "--target", "depth"])
    _one_line(code, err, re.escape(str(binary)))
    bom = _copy(small_csv, tmp_path / "bom.csv")
    bom.write_bytes(b"\xef\xbb\xbf" + small_csv.read_bytes())
    a, b = load_survey(bom), load_survey(small_csv)
    assert a.n == b.n and np.array_equal(a.columns["t"], b.columns["t"])


def test_duplicate_column_names_are_refused(small_csv, tmp_path, capsys):
    header, rows = csv_rows(small_csv)
    header[header.index("water_temp")] = "depth"
    code, _, err = _run(
        capsys, ["fit", write_csv_rows(tmp_path / "dup.csv", header, rows), "--target", "t"]
    )
    _one_line(code, err, "'depth' appear more than once")


# --- model specs and user functions ----------------------------------------------------------------


SPECS = [
    ("terms = 5\n", "terms must be a list of strings"),
    ('terms = ["const", "gp(depth, matern99)"]\n', "unknown kernel 'matern99'; kernels are"),
    (
        '[[term]]\nkind = "gp"\ninputs = ["depth"]\nkernel = "gaussian"\n',
        "unknown kernel 'gaussian'",
    ),
    ('[[term]]\nkind = "gp"\ninputs = 3\n', "inputs must be a list of column names"),
    ('[[term]]\nkind = "user"\ninputs = ["depth"]\n', 'needs function = "module:function"'),
    ('term = "depth"\n', r"write each term table as \[\[term\]\]"),
    ('target = 3\nterms = ["const"]\n', "target must be a column name"),
    ('terms = ["const"]\ntargett = "depth"\n', "unknown key"),
    ('terms = ["const", "gp(depth + t)"]\n', "not a column name"),
]


@pytest.mark.parametrize(("text", "expect"), SPECS)
def test_bad_spec_is_one_line_that_says_what_is_wrong(small_csv, tmp_path, capsys, text, expect):
    spec = tmp_path / "spec.toml"
    spec.write_text(text)
    code, _, err = _run(capsys, ["fit", small_csv, "--target", "depth", "--model", spec])
    _one_line(code, err, expect)


def test_binary_or_folder_spec(small_csv, tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_bytes(bytes(range(256)))
    code, _, err = _run(capsys, ["fit", small_csv, "--target", "depth", "--model", spec])
    _one_line(code, err, "not a TOML text file")
    code, _, err = _run(capsys, ["fit", small_csv, "--target", "depth", "--model", tmp_path])
    _one_line(code, err, "is a folder")


USER = {
    "raises": ("def f(depth, k=1.0):\n    raise RuntimeError('sensor table missing')\n",
               "the function raised RuntimeError: sensor table missing"),
    "nan": ("import numpy as np\ndef f(depth, k=1.0):\n    return np.where(depth > np.median(depth), np.nan, k * depth)\n",
            "returned NaN or inf"),
    "inf": ("def f(depth, k=1.0):\n    return k / (depth - depth)\n", "returned NaN or inf"),
    "shape": ("import numpy as np\ndef f(depth, k=1.0):\n    return np.ones((len(depth), 2))\n",
              r"returned shape \(\d+, 2\)"),
    "default": ("def f(depth, k='one'):\n    return depth\n", "must default to a finite number"),
    "syntax": ("def f(depth:\n", "failed to load"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(USER))
def test_user_function_failures_name_the_function(small_csv, tmp_path, capsys, monkeypatch, case):
    code_text, expect = USER[case]
    (tmp_path / f"laws_{case}.py").write_text(code_text)
    monkeypatch.chdir(tmp_path)
    table = _copy(small_csv, tmp_path / "survey.csv")
    path_before, modules_before = list(sys.path), set(sys.modules)
    code, _, err = _run(
        capsys,
        ["fit", table, "--target", "current_speed", "--effects", f"user(depth, laws_{case}:f)",
         "--quiet", "--no-plots"],
    )  # fmt: skip
    _one_line(code, err, f"user term 'laws_{case}:f'", expect)
    assert not (tmp_path / "survey.csv.forcemap" / "history.json").exists()  # nothing saved
    # the module was loaded from its file, explicitly: sys.path and sys.modules are untouched
    assert sys.path == path_before and f"laws_{case}" not in set(sys.modules) - modules_before


def test_user_function_is_loaded_from_the_current_folder_without_sys_path(
    small_csv, tmp_path, capsys, monkeypatch
):
    (tmp_path / "mylaws.py").write_text(
        "def manning(depth, k=1.0):\n    return k * depth ** (2 / 3)\n"
    )
    monkeypatch.chdir(tmp_path)
    table = _copy(small_csv, tmp_path / "survey.csv")
    path_before = list(sys.path)
    code, out, err = _run(
        capsys,
        ["fit", table, "--target", "current_speed", "--effects", "user(depth, mylaws:manning)",
         "--quiet", "--no-plots"],
    )  # fmt: skip
    assert code == 0, err
    assert "user(depth, mylaws:manning): k=" in out
    assert sys.path == path_before and "mylaws" not in sys.modules
    # a missing module is found out before the table is read
    code, _, err = _run(
        capsys,
        ["fit", "no-such-table.csv", "--target", "depth", "--effects", "user(depth, nolaws:f)"],
    )
    _one_line(code, err, "cannot import 'nolaws': no file nolaws.py here and no installed module")


# --- the demo writes only where it may ------------------------------------------------------------


def test_demo_refuses_a_folder_holding_other_data(tmp_path, capsys):
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs" / "run-2026-05-01.mcap").write_bytes(b"a field log")
    code, _, err = _run(capsys, ["demo", "-o", tmp_path])
    _one_line(code, err, "holds files that no demo wrote")
    assert (tmp_path / "logs" / "run-2026-05-01.mcap").read_bytes() == b"a field log"
    for speed in ("0", "nan"):
        code, _, err = _run(capsys, ["demo", "-o", tmp_path / "new", f"--speed={speed}"])
        _one_line(code, err, "--speed must be a finite number above 0")
    assert not (tmp_path / "new").exists()
