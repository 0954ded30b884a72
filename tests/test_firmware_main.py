"""The board entry point, firmware_bridge/main.py, under the unix-port MicroPython with fake
``machine``/``time``/``os`` modules: it wires pins, counters, ADC, watchdog and stdout like a board."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from forcemap.protocol import wire

from tests import tools

ROOT = Path(__file__).resolve().parents[1]

BOARDS = {
    "Arduino Nano RP2040 Connect with RP2040": (
        "Arduino Nano RP2040 Connect",
        "hard=True counters=0 atten=None timer=-1",
    ),
    "Arduino Nano ESP32 with ESP32S3": (
        "Arduino Nano ESP32",
        "hard=False counters=4 atten=3 timer=0",
    ),
}


def smoke(machine_name, *extra):
    r = subprocess.run(
        [
            tools.micropython(),
            str(ROOT / "sim_devices/upy/main_smoke.py"),
            str(tools.board_lib()),
            machine_name,
            "8",
            *extra,
        ],
        capture_output=True,
    )
    assert r.returncode == 0, r.stderr.decode()
    return wire.StreamDecoder().feed(r.stdout), r.stderr.decode()


@pytest.mark.parametrize("machine_name", list(BOARDS))
def test_main_streams_frames(machine_name):
    frames, info = smoke(machine_name)
    board, wiring = BOARDS[machine_name]
    assert frames[0].msg_type == wire.HELLO
    assert frames[0].fields["board"] == board and frames[0].fields["reset_cause"] == 3
    samples = [f for f in frames if f.msg_type == wire.SAMPLE]
    assert [f.t_us for f in samples] == list(range(0, 250_000 * len(samples), 250_000))
    assert all(f.fields["vane_raw"] == 29527 for f in samples)
    assert f"pins=6 {wiring} emergency=100" in info
    # the loop stopped without Ctrl-C: the timer no longer feeds the WDT, so the board would reset
    assert "interrupted=False repl_feeds=0" in info


@pytest.mark.parametrize("machine_name", list(BOARDS))
def test_ctrl_c_keeps_the_repl_alive(machine_name):
    _, info = smoke(machine_name, "kbd")
    assert "interrupted=True repl_feeds=2" in info
