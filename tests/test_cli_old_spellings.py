"""Every old spelling of an option still works for one release, with a one-line note naming the new one.

The real commands run on small inputs (a 40-fix NMEA capture, 400 s of the synthetic river); the note is
one line on stderr, ``forcemap CMD: note: OLD is deprecated ...; use NEW``, and the command does what the
new spelling does. The list is docs/CLI.md's table of deprecations.
"""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from forcemap.host.cli import build_parser, main
from forcemap.host.log.mcap import read_messages
from mcap.reader import make_reader

from bench.synth_survey import make_survey
from tests.test_io_bad_input import nmea_capture

ROOT = Path(__file__).resolve().parents[1]
BOAT = ROOT / "host" / "data" / "boat.example.toml"


def notes(err: str) -> list[str]:
    return [line for line in err.splitlines() if ": note: " in line and "deprecated" in line]


def assert_notes(err: str, command: str, *pairs: tuple[str, str]) -> None:
    """One note per old spelling, each naming the new spelling, and no other note."""
    found = notes(err)
    assert len(found) == len(pairs), err
    for (old, new), line in zip(pairs, found, strict=True):
        assert line.startswith(f"forcemap {command}: note: {old} is deprecated"), line
        assert line.endswith(new) or f"use {new}" in line, line


@pytest.fixture(scope="module")
def small_table(tmp_path_factory) -> Path:
    """400 s of the synthetic river, with one fit of depth recorded (for history)."""
    table = make_survey("river", ["depth_current"], 5, 400.0, tmp_path_factory.mktemp("old"))
    assert main(["fit", str(table), "--target", "depth", "--quiet", "--no-plots"]) == 0
    return table


def test_import_export_and_log_info_old_spellings(tmp_path, capsys):
    capture = nmea_capture(tmp_path / "capture.txt")
    argv = ["import", str(capture), "--format", "nmea", "--config", str(BOAT), "--out", str(tmp_path / "new")]  # fmt: skip
    assert main(argv) == 0
    assert_notes(
        capsys.readouterr().err, "import",
        ("--format", "--from nmea|tlog|dataflash"), ("--config", "--boat BOAT.toml"),
        ("--out", "-o/--output DIR (an existing folder)"),
    )  # fmt: skip
    log = tmp_path / "new" / "capture.mcap"  # --out DIR still creates the folder
    assert sum(1 for _ in read_messages(log, "/samples")) == 40
    bad = tmp_path / "bad.toml"
    bad.write_text('[vane]\nvref = "x"\n')
    assert main(["import", str(capture), "--config", str(bad), "-o", str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err
    assert_notes(err, "import", ("--config", "--boat BOAT.toml"))
    assert "vane.vref" in err  # --config's file is the one read

    assert main(["export", str(log), "-f", "kml"]) == 0
    assert_notes(capsys.readouterr().err, "export", ("-f", "--to FORMAT, or an output suffix"))
    assert log.with_suffix(".kml").read_text().startswith("<?xml")
    out = tmp_path / "survey.data"
    assert main(["export", str(log), "--format", "parquet", "-o", str(out)]) == 0
    assert_notes(capsys.readouterr().err, "export", ("--format", "--to FORMAT"))
    assert out.read_bytes()[:4] == b"PAR1"

    for argv in (["log", "info", "--json", str(log)], ["log", "info", str(log), "--json"]):
        assert main(argv) == 0
        captured = capsys.readouterr()
        [info] = json.loads(captured.out)  # nothing but the JSON on stdout, as with --json -
        assert info["topics"]["/samples"]["count"] == 40
        assert_notes(
            captured.err, "log info", ("--json without a value", "--json - (or --json PATH)")
        )


def test_the_new_spellings_print_no_note(tmp_path, capsys):
    capture = nmea_capture(tmp_path / "capture.txt")
    out = tmp_path / "c.mcap"
    assert (
        main(["import", str(capture), "--from", "nmea", "--boat", str(BOAT), "-o", str(out)]) == 0
    )
    assert main(["export", str(out), "-o", str(tmp_path / "c.kml")]) == 0
    assert main(["log", "info", str(out), "--json", str(tmp_path / "info.json")]) == 0
    err = capsys.readouterr().err
    assert notes(err) == [] and "note:" not in err
    assert json.loads((tmp_path / "info.json").read_text())[0]["topics"]["/samples"]["count"] == 40


def test_history_plot(small_table, tmp_path, capsys):
    png = tmp_path / "errors.png"
    assert main(["history", str(small_table), "--plot", str(png)]) == 0
    assert_notes(capsys.readouterr().err, "history", ("--plot", "-o/--output PNG"))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_sim_effects_truth_and_a_bare_duration(tmp_path, capsys):
    truth = tmp_path / "truth"
    argv = ["sim", "--effects", "gusts", "--duration", "30", "--truth", str(truth), "--seed", "3"]
    assert main(argv) == 0
    assert_notes(
        capsys.readouterr().err, "sim",
        ("--effects", "--phenomena LIST"), ("--duration 30 (a number without a unit)", "--duration 30s"),
        ("--truth", "-o/--output DIR"),
    )  # fmt: skip
    meta = json.loads((truth / "effects.json").read_text())
    assert meta["duration"] == 30.0 and "gusts" in json.dumps(meta)


def test_demo_out_effect_and_duration(tmp_path, capsys):
    """The demo takes minutes: its parser stores the old spellings where the new ones go, and a
    file given as the old --out is refused as the new -o's file is."""
    args = build_parser("demo").parse_args(
        ["demo", "--effect", "gusts", "--duration", "600", "--out", "d"]
    )
    assert (args.phenomena, args.duration, args.output) == ("gusts", 600.0, "d")
    assert_notes(
        capsys.readouterr().err, "demo",
        ("--effect", "--phenomena NAME"), ("--duration 600 (a number without a unit)", "600s"),
        ("--out", "-o/--output DIR"),
    )  # fmt: skip
    f = tmp_path / "a-file"
    f.write_text("not a folder\n")
    assert main(["demo", "--out", str(f)]) == 2
    err = capsys.readouterr().err
    assert_notes(err, "demo", ("--out", "-o/--output DIR"))
    assert f"forcemap demo: -o {f} is a file" in err


def test_run_config_out_rotate_min_and_clock_wait(tmp_path):
    """The daemon itself, on a UDP port that never speaks: the log lands in --out, with --config's
    file in its metadata; SIGTERM ends it cleanly."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "logs"
    argv = [sys.executable, "-m", "forcemap.host.cli", "run", "--nmea", f"udp:{port}",
            "--config", str(BOAT), "--out", str(out), "--rotate-min", "2", "--clock-wait", "5", "--quiet"]  # fmt: skip
    proc = subprocess.Popen(
        argv, cwd=ROOT, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True
    )
    assert proc.stderr is not None
    head = []
    try:
        # the notes, then one JSON line per event: "start" comes once the daemon handles SIGTERM
        for line in proc.stderr:
            head.append(line)
            if '"event":"start"' in line:
                break
        proc.send_signal(signal.SIGTERM)
        _, rest = proc.communicate(timeout=60)
        err = "".join(head) + rest
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert_notes(
        err, "run",
        ("--config", "--boat BOAT.toml"), ("--out", "-o/--output DIR"),
        ("--rotate-min", "--rotate-every DURATION (e.g. 60m)"),
        ("--clock-wait 5 (a number without a unit)", "--clock-wait 5s"),
    )  # fmt: skip
    [log] = out.glob("*.mcap")
    with open(log, "rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert meta["boat_toml"]["path"] == str(BOAT)
    assert meta["boat_toml"]["text"] == BOAT.read_text(encoding="utf-8")
    parsed = build_parser("run").parse_args(["run", "--rotate-min", "2", "--clock-wait", "5"])
    assert (parsed.rotate_s, parsed.clock_wait) == (120.0, 5.0)


def test_the_target_rule_is_the_same_in_fit_and_diagnose(small_table, tmp_path, capsys):
    """--target, or else the --model spec's target; neither is the same one-line error in both."""
    for command in ("fit", "diagnose"):
        assert main([command, str(small_table), "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert (
            err
            == f"forcemap {command}: no target: give --target COLUMN (or target = ... in the --model spec)"
        )
    spec = tmp_path / "spec.toml"
    spec.write_text('target = "depth"\nterms = ["const", "gp(position, matern32)"]\n')
    args = ["--model", str(spec), "--quiet", "--json", "-"]
    assert main(["diagnose", str(small_table), *args, "--rounds", "1"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["target"] == "depth"  # stdout: nothing but the JSON
    assert main(["fit", str(small_table), *args, "--no-plots"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["target"] == "depth"
    assert "saved fit" in captured.err  # the human text went to stderr


def test_rotate_and_clock_wait_refuse_what_is_not_a_duration(capsys):
    for argv in (["run", "--rotate-every", "20 minutes"], ["run", "--clock-wait=-5s"]):
        with pytest.raises(SystemExit) as e:
            build_parser("run").parse_args(argv)
        assert e.value.code == 2
        assert "bad duration" in capsys.readouterr().err
