"""Issue 11's rows for `export`, `import` and `run`: one line and exit 2, nothing lost, nothing half written."""

from __future__ import annotations

import hashlib
import time
from pathlib import Path

import pytest
from forcemap.host.cli import main
from forcemap.host.cli.run import CLOCK_WAIT_S
from forcemap.host.log.mcap import McapLog, read_messages

from tests.test_daemon_support import nmea_line
from tests.test_export import T0, _log


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def listing(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def one_line(capsys, command: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"forcemap {command}: "), err
    assert "Traceback" not in err
    return err


def random_bytes(path: Path, n: int = 20000, seed: int = 7) -> Path:
    import random

    path.write_bytes(random.Random(seed).randbytes(n))
    return path


# --- export -----------------------------------------------------------------------------------


def test_export_of_a_table_is_refused_and_the_table_kept(tmp_path, capsys):
    table = tmp_path / "survey.csv"
    table.write_text("t,lat,lon\n1,47,8\n")
    before, files = digest(table), listing(tmp_path)
    assert main(["export", str(table)]) == 2
    assert "not an MCAP log" in one_line(capsys, "export")
    assert digest(table) == before and listing(tmp_path) == files


def test_export_output_that_is_the_input_is_refused_even_with_force(tmp_path, capsys):
    log = _log(tmp_path)
    before = digest(log)
    for extra in ([], ["--force"]):
        assert main(["export", str(log), "-o", str(log), *extra]) == 2
        assert "also an input" in one_line(capsys, "export")
    assert digest(log) == before


def test_export_never_replaces_an_existing_output_without_force(tmp_path, capsys):
    log = _log(tmp_path)
    out = tmp_path / "existing.csv"
    out.write_text("keep me\n")
    assert main(["export", str(log), "-o", str(out)]) == 2
    assert "--force" in one_line(capsys, "export")
    assert out.read_text() == "keep me\n"
    assert main(["export", str(log), "-o", str(out), "--force"]) == 0
    assert out.read_text().startswith("t,lat,lon") and len(out.read_text().splitlines()) == 41


@pytest.mark.parametrize("fmt", ["csv", "parquet", "geojson", "kml"])
def test_export_writes_atomically_and_leaves_no_temporary_file(tmp_path, fmt):
    log = _log(tmp_path)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    assert main(["export", str(log), "--to", fmt, "-o", str(out_dir)]) == 0
    assert listing(out_dir) == {log.with_suffix("." + fmt).name}  # a folder: named like the input


def test_export_of_a_log_without_samples_writes_nothing(tmp_path, capsys):
    with McapLog(tmp_path / "logs") as log:
        log.write("/depth", int(T0 * 1e9), {"t": T0, "depth": 3.0})
    for fmt in ("csv", "kml"):
        assert main(["export", str(log.path), "--to", fmt]) == 2
        assert "no " in one_line(capsys, "export")
    assert listing(tmp_path / "logs") == {log.path.name}


def test_export_of_a_folder_without_logs_or_a_missing_file(tmp_path, capsys):
    assert main(["export", str(tmp_path)]) == 2
    assert "no .mcap files" in one_line(capsys, "export")
    assert main(["export", str(tmp_path / "nope.mcap")]) == 2
    assert "no such file" in one_line(capsys, "export")
    log = _log(tmp_path)
    assert main(["export", str(log), "-o", f"{tmp_path / 'missing'}/"]) == 2
    assert "does not exist" in one_line(capsys, "export")
    assert not (tmp_path / "missing").exists()


# --- import -----------------------------------------------------------------------------------


def nmea_capture(path: Path, n: int = 40) -> Path:
    lines = [
        nmea_line(f"GPRMC,1200{i % 60:02d}.00,A,4700.000,N,00800.000,E,3.0,90.0,010626,,,A")
        + nmea_line(f"SDDPT,{2 + i / 10:.1f},0.3")
        for i in range(n)
    ]
    path.write_bytes(b"".join(lines))
    return path


@pytest.mark.parametrize("name", ["junk.bin", "junk.dat", "junk.tlog"])
def test_import_of_random_bytes_names_no_format_and_leaves_nothing(tmp_path, capsys, name):
    junk = random_bytes(tmp_path / name)
    out = tmp_path / "out"
    out.mkdir()
    assert main(["import", str(junk), "-o", str(out)]) == 2
    err = one_line(capsys, "import")
    assert "DataFlash" not in err
    assert listing(out) == set()


@pytest.mark.parametrize("fmt", ["tlog", "nmea"])
def test_import_with_a_format_on_random_bytes_leaves_no_partial_mcap(tmp_path, capsys, fmt):
    # seeds where some 8-byte "times" are beyond what MCAP can hold (they crashed the writer)
    junk = random_bytes(tmp_path / "junk.dat", n=200_000)
    assert main(["import", str(junk), "--from", fmt, "-o", str(tmp_path / "out")]) == 2
    err = one_line(capsys, "import")
    assert ("MAVLink" if fmt == "tlog" else "NMEA") in err and "DataFlash" not in err
    assert listing(tmp_path / "out") == set()


def test_import_and_export_take_the_same_output_options(tmp_path, capsys):
    capture = nmea_capture(tmp_path / "capture.txt")
    before = digest(capture)
    out = tmp_path / "survey.mcap"
    assert main(["import", str(capture), "-o", str(out)]) == 0
    assert sum(1 for _ in read_messages(out, "/nmea/sentence")) == 80
    first = digest(out)
    capsys.readouterr()
    assert main(["import", str(capture), "--output", str(out)]) == 2  # exists: needs --force
    assert "--force" in one_line(capsys, "import")
    assert digest(out) == first
    assert main(["import", str(capture), "-o", str(out), "--force"]) == 0
    # no -o: beside the input, as export does; -o DIR names it like the input
    assert main(["import", str(capture)]) == 0
    assert (tmp_path / "capture.mcap").is_file()
    (tmp_path / "new").mkdir()
    assert main(["import", str(capture), "-o", str(tmp_path / "new")]) == 0
    assert listing(tmp_path / "new") == {"capture.mcap"}
    assert digest(capture) == before
    capsys.readouterr()
    assert main(["import", str(capture), "-o", str(capture)]) == 2
    assert "also an input" in one_line(capsys, "import")
    assert digest(capture) == before


# --- run --------------------------------------------------------------------------------------


def test_run_with_a_missing_sim_clock_gives_up_in_a_few_seconds(tmp_path, capsys, monkeypatch):
    """The give-up after `--clock-wait` (default CLOCK_WAIT_S, a few seconds; here 1 s, the same path)."""
    monkeypatch.chdir(tmp_path)
    assert 2.0 <= CLOCK_WAIT_S <= 30.0
    t0 = time.monotonic()
    argv = ["run", "--depth", "x", "--clock", "sim:MISSING", "--clock-wait", "1s", "-o", "logs"]
    assert main(argv) == 2
    elapsed = time.monotonic() - t0
    err = one_line(capsys, "run")
    assert "MISSING" in err and "forcemap sim" in err
    assert 1.0 <= elapsed < 1.0 + 20  # the upper bound only catches a hang
    assert not (tmp_path / "logs").exists()


@pytest.mark.parametrize(
    "args, words",
    [
        (["--nmea", "udp:host:notaport"], "udp:host:notaport"),
        (["--mavlink", "udp:host:notaport"], "udp:host:notaport"),
        (["--nmea", "udp:0"], "port from 1 to 65535"),
        (["--depth", "x", "--rotate-mb", "0"], "--rotate-mb"),
        (["--depth", "x", "--rotate-every", "0s"], "--rotate-every"),
        (["--depth", "x", "--rotate-mb", "nan"], "--rotate-mb"),
    ],
)
def test_run_refuses_what_cannot_work(tmp_path, capsys, args, words):
    assert main(["run", *args, "-o", str(tmp_path / "logs")]) == 2
    assert words in one_line(capsys, "run")
    assert not (tmp_path / "logs").exists()
