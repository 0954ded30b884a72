"""`forcemap run --mavlink PORT --mission MISSION --replan` on the simulator's ptys.

The daemon stamps with the simulator's virtual clock; the replanner's own waits are host time, so this
asserts what happens (the mission read back and checked, a decision after the first line, logged as
/plan/replan and listed by `forcemap log info`), not how fast: whether the decision was in time for
the turn depends on the machine's load (a late one is recorded as not sent, never flown mid-line).
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from forcemap.host.cli import main
from forcemap.host.log.mcap import read_messages
from forcemap.host.report.mission_section import mission_section
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.vessel.mission import save_waypoints
from forcemap.host.workbench.table import load_survey

from bench.inflight_loop import mission
from tests.test_daemon_support import ROOT, DaemonProcess, mcap_files

SPEED = 10


def test_replan_needs_mavlink_and_mission_needs_replan(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["run", "--nmea", "/dev/null", "--replan"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--replan needs --mavlink" in err[0]
    assert main(["run", "--nmea", "/dev/null", "--mission", "lawnmower"]) == 2
    assert "only used with --replan" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("live", [False, True], ids=["refit", "live-map"])
def test_run_replan_on_ptys(tmp_path: Path, capsys, live: bool) -> None:  # type: ignore[no-untyped-def]
    """Without --live the replanner refits the maps itself; with it, it reads the live map's grids."""
    scen = sc.load("river")
    wpl = tmp_path / "lawnmower.waypoints"
    save_waypoints(wpl, mission("river"), LocalFrame(scen.lat0, scen.lon0))
    ports, out = tmp_path / "ports", tmp_path / "out"
    daemon = DaemonProcess(
        out, {"mavlink": str(ports / "mavlink"), "bridge": str(ports / "bridge")},
        "--clock", f"sim:{ports / 'clock'}", "--clock-wait", "60s",
        "--mission", str(wpl), "--replan",
        *(["--live", "127.0.0.1:0", "--map-every", "30s"] if live else []),
    )  # fmt: skip
    sim = subprocess.Popen(
        [sys.executable, "-m", "forcemap.host.cli", "sim", "--scenario", "river", "--mission",
         str(wpl), "--speed", str(SPEED), "--duration", "4m", "--ports", str(ports)],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        daemon.wait_for(lambda e: "following the autopilot" in e.get("message", ""), 120.0)
        assert sim.wait(600) == 0, sim.stderr.read()  # type: ignore[union-attr]
        daemon.wait_for(lambda e: "after line 1" in e.get("message", ""), 120.0)
        assert daemon.stop(signal.SIGTERM) == 0
    finally:
        for p in (sim, daemon.proc):
            if p.poll() is None:
                p.kill()
    [path] = mcap_files(out)
    recs = [m.message for m in read_messages(path, "/plan/replan")]
    assert recs and recs[0]["line_done"] == 0 and recs[0]["mode"] == "AUTO"
    assert recs[0]["reason"] and recs[0]["map_samples"] and recs[0]["old_remaining"]
    capsys.readouterr()
    assert main(["log", "info", str(path)]) == 0
    text = capsys.readouterr().out
    assert "in-flight replanning: " in text and "after line 1" in text
    # the report's mission section, from the log itself
    parts = "\n".join(mission_section(path, load_survey(path)))
    assert "<h3>In flight</h3>" in parts and parts.count("<tr><td>") == len(recs)
