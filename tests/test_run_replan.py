"""`forcemap run --mavlink PORT --mission MISSION --replan` on the simulator's ptys.

The daemon stamps with the simulator's virtual clock; the replanner's own waits are host time, so this
asserts what happens (the mission read back and checked, a decision after the first line, logged as
/plan/replan and listed by `forcemap log info`), not how fast: whether the decision was in time for
the turn depends on the machine's load (a late one is recorded as not sent, never flown mid-line).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from forcemap.host.cli import main
from forcemap.host.live.mission_layer import TOPIC as MISSION
from forcemap.host.log.mcap import read_messages
from forcemap.host.plan.mission_io import read_mission
from forcemap.host.report.mission_section import mission_section
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.vessel.mission import save_waypoints
from forcemap.host.workbench.survey.table import load_survey

from bench.inflight_loop import mission
from bench.live_client import LiveClient
from tests.test_daemon_support import ROOT, DaemonProcess, mcap_files
from tests.test_live import mcap_messages

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
    client = None
    try:
        if live:  # a viewer, from before the mission is read back
            url = daemon.wait_for(lambda e: e.get("event") == "live", 60.0)["connect"]
            client = LiveClient(url)
            client.wait_ready()
        daemon.wait_for(lambda e: "following the autopilot" in e.get("message", ""), 120.0)
        assert sim.wait(600) == 0, sim.stderr.read()  # type: ignore[union-attr]
        daemon.wait_for(lambda e: "after line 1" in e.get("message", ""), 120.0)
        assert daemon.stop(signal.SIGTERM) == 0
    finally:
        for p in (sim, daemon.proc):
            if p.poll() is None:
                p.kill()
        if client is not None:
            client.close()
    [path] = mcap_files(out)
    recs = [m.message for m in read_messages(path, "/plan/replan")]
    if client is not None:
        _live_shows_the_decisions(client, path, read_mission(wpl).lines_latlon)
    assert recs and recs[0]["line_done"] == 0 and recs[0]["mode"] == "AUTO"
    first = recs[0]
    assert first["reason"]
    if live and first["reason"] == "no map yet":
        # the map process had not finished its first fit by the turn (a loaded machine): the mission
        # is kept as it was; the live board feeding the replanner is test_plan_inflight's
        assert not first["uploaded"] and not first["map_samples"] and not first["new_remaining"]
    else:
        assert first["map_samples"] and first["old_remaining"]
    capsys.readouterr()
    assert main(["log", "info", str(path)]) == 0
    text = capsys.readouterr().out
    assert "in-flight replanning: " in text and "after line 1" in text
    # the report's mission section, from the log itself
    parts = "\n".join(mission_section(path, load_survey(path)))
    assert "<h3>In flight</h3>" in parts and parts.count("<tr><td>") == len(recs)


def _live_shows_the_decisions(client: LiveClient, path: Path, lines) -> None:  # type: ignore[no-untyped-def]
    """The viewer got every /plan/replan as logged, byte for byte, and /map/mission (not logged)."""
    logged = mcap_messages(path)
    replans = [m for m in logged if m[0] == "/plan/replan"]
    assert replans and [m for m in client.messages if m[0] == "/plan/replan"] == replans
    assert not client.invalid
    assert MISSION not in {t for t, _, _ in logged}
    shown = [json.loads(json.loads(p)["geojson"]) for t, _, p in client.messages if t == MISSION]
    assert shown
    parts = {f["properties"]["name"]: f["geometry"]["coordinates"] for f in shown[-1]["features"]}
    assert sum(k.startswith("intended line") for k in parts) == len(lines)
    assert parts["intended line 1"][0] == [round(lines[0][0][1], 7), round(lines[0][0][0], 7)]
    plan = next(v for k, v in parts.items() if k.startswith("plan: "))
    uploads = [json.loads(p) for _, _, p in replans if json.loads(p)["uploaded"]]
    if uploads:  # the plan shown ends with the last accepted upload's remaining mission
        tail = [[round(lon, 7), round(lat, 7)] for lat, lon, _ in uploads[-1]["new_remaining"]]
        assert plan[-len(tail) :] == tail
    fixes = [json.loads(p) for t, _, p in logged if t == "/fix"]
    track = parts["flown track"]
    assert 10 <= len(track) < len(fixes)  # decimated, 3 m apart
    assert track[-1] in [[round(f["longitude"], 7), round(f["latitude"], 7)] for f in fixes]
