"""`forcemap sim`: --list, --help, a short accelerated run, and a clean stop on Ctrl-C."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from forcemap.host.cli import main
from forcemap.host.cli.common import parse_duration
from forcemap.host.vessel import mission, scenario
from forcemap.sim_devices import effects, faults


def test_list_names_everything(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["sim", "--list"]) == 0
    out = capsys.readouterr().out
    for name in [
        *scenario.builtin_names(),
        *mission.builtin_names(),
        *effects.CATALOGUE,
        *faults.KINDS,
        "default",
    ]:
        assert f"  {name}" in out, name


def test_help_teaches(capsys) -> None:  # type: ignore[no-untyped-def]
    try:
        main(["sim", "--help"])
    except SystemExit:
        pass
    out = capsys.readouterr().out
    assert "--speed 50" in out and "--clock sim:" in out and "--faults" in out


def test_durations() -> None:
    assert [parse_duration(s) for s in ("600s", "90s", "30m", "1.5h", "1h30m")] == [
        600,
        90,
        1800,
        5400,
        5400,
    ]


def test_short_run_writes_truth(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    rc = main(["sim", "--scenario", "lake", "--duration", "20s", "--speed", "200", "--phenomena", "gusts",
               "--faults", "default", "--ports", str(tmp_path / "p"), "-o", str(tmp_path / "t"), "--seed", "4"])  # fmt: skip
    assert rc == 0
    out = capsys.readouterr().out
    assert str(tmp_path / "p" / "bridge") in out and str(tmp_path / "p" / "mavlink") in out
    meta = json.loads((tmp_path / "t" / "effects.json").read_text())
    assert meta["seed"] == 4 and meta["effects"][0]["name"] == "gusts" and len(meta["faults"]) == 8
    assert (tmp_path / "t" / "fields.npz").exists() and (tmp_path / "t" / "samples.csv").exists()
    assert not (tmp_path / "p" / "bridge").exists()  # the ports go away with the simulator


def test_bad_arguments(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["sim", "--phenomena", "nope", "--ports", "/tmp/x-never"]) == 2
    assert main(["sim", "--duration", "10s"]) == 2
    assert "unknown effect" in capsys.readouterr().err


def test_ctrl_c_stops_cleanly(tmp_path: Path) -> None:
    ports, truth = tmp_path / "p", tmp_path / "t"
    proc = subprocess.Popen(
        [sys.executable, "-m", "forcemap.host.cli", "sim", "--scenario", "river", "--duration", "1h", "--speed", "5",
         "--ports", str(ports), "-o", str(truth)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert proc.stdout is not None
    lines = []
    for line in proc.stdout:
        lines.append(line)
        # the first progress line is at t = 0; stop once virtual time has moved
        if line.lstrip().startswith("t=") and float(line.split()[1]) > 0:
            break
    assert (ports / "bridge").is_symlink()
    proc.send_signal(signal.SIGINT)
    rest, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "stopped" in rest
    assert not (ports / "bridge").exists()
    meta = json.loads((truth / "effects.json").read_text())
    assert 0 < meta["duration"] < 3600


@pytest.mark.parametrize("speed", ["0", "-5", "nan", "inf"])
def test_a_speed_that_cannot_run_is_refused(speed, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    # a clock at x0 never advances: the simulator used to hang at t = 0 with no message
    assert main(["sim", f"--speed={speed}", "--ports", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--speed must be a finite number above 0" in err
    assert not (tmp_path / "p").exists()


def test_ports_or_truth_in_a_file_is_refused(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    f = tmp_path / "notes.txt"
    f.write_text("mine\n")
    assert main(["sim", "--ports", str(f)]) == 2
    assert main(["sim", "--ports", str(tmp_path / "p"), "-o", str(f)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("is a file; give a folder") == 2
    assert f.read_text() == "mine\n"
