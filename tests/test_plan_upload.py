"""`forcemap plan --upload`: the mission protocol against the simulator's autopilot on a real pty.

The ground side is pymavlink over pyserial on the pty the simulator serves; the vehicle side is the
simulator's autopilot (sim_devices/mission_protocol.py), which flies what it accepts. The timeouts are
generous wall-clock bounds (the uploader waits 1.5 s per request, five times), never speed assumptions.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.plan.upload import upload_file
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel import waypoints as wp
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.ports import PortSet, run_live


def mission_file(tmp: Path) -> Path:
    """A small survey with two speed changes, as Mission Planner would save it."""
    scen = sc.load("river")
    geo = LocalFrame(scen.lat0, scen.lon0)
    xy = np.array([[-100.0, 0.0], [-50.0, 0.0], [0.0, 0.0], [0.0, 20.0], [-100.0, 20.0]])
    m = ms.Mission("t", "", xy, False, np.array([np.nan, 4.5, 4.5, np.nan, 2.0]))
    path = tmp / "m.waypoints"
    ms.save_waypoints(path, m, geo)
    return path


def run_upload(tmp: Path, drop: set[int], nak_at: int | None) -> tuple[Simulation, int]:
    ports = PortSet(tmp / "ports")
    stop = threading.Event()
    box: dict[str, Simulation] = {}

    def factory(**kw: object) -> Simulation:
        sim = Simulation("river", "lawnmower", [], None, seed=0, **kw)  # type: ignore[arg-type]
        box["sim"] = sim
        return sim

    def live() -> None:
        run_live(factory, ports, 3600.0, 4.0, stop)

    th = threading.Thread(target=live, daemon=True)
    th.start()
    try:
        deadline = time.monotonic() + 30.0
        while "sim" not in box or not hasattr(box["sim"], "autopilot"):
            assert time.monotonic() < deadline, "the simulator did not start"
            time.sleep(0.05)
        rx = box["sim"].autopilot.uplink
        rx.drop_request, rx.nak_at = set(drop), nak_at
        n = upload_file(ports.path("mavlink"), mission_file(tmp), progress=False)
        deadline = time.monotonic() + 30.0
        while box["sim"].mission.name != "uploaded":
            assert time.monotonic() < deadline, "the accepted mission was not flown"
            time.sleep(0.05)
    finally:
        stop.set()
        th.join(timeout=60.0)
        ports.close()
    return box["sim"], n


def expected_items(tmp: Path) -> list[tuple]:
    home, items = wp.read_wpl(mission_file(tmp))
    return [(i.command, i.lat_e7, i.lon_e7, i.params) for i in [home, *items]]


@pytest.mark.parametrize(
    ("drop", "nak_at"), [(set(), None), ({3}, None), (set(), 4)], ids=["clean", "dropped", "nak"]
)
def test_upload_is_acknowledged_and_flown(
    tmp_path: Path, drop: set[int], nak_at: int | None
) -> None:
    sim, n = run_upload(tmp_path, drop, nak_at)
    got = [
        (i.command, i.lat_e7, i.lon_e7, tuple(float(p) for p in i.params))
        for i in sim.autopilot.uplink.accepted
    ]
    want = expected_items(tmp_path)
    # the dropped request and the NAK did happen, and the upload recovered from them
    assert not sim.autopilot.uplink.drop_request and sim.autopilot.uplink.nak_at is None
    assert n == len(want) == 8  # home, 5 waypoints, 2 speed changes
    assert got == [(c, la, lo, tuple(float(p) for p in ps)) for c, la, lo, ps in want]
    # it flies what it received, from where it was: as Rover, a mission accepted in AUTO keeps the
    # current item number (the boat was going for item 2 or 3 of the lawnmower), so it goes for the
    # first waypoint at or after that item and on through the last, at the speeds given
    seqs = list(sim.mission.seqs[1:])
    assert seqs == [3, 4, 5, 7]  # the file's NAV_WAYPOINTs are items 1, 3, 4, 5 and 7
    assert len(sim.mission.waypoints) == len(seqs) + 1
    assert np.nanmax(sim.mission.speeds) == pytest.approx(4.5)
    assert sim.mission.speeds[-1] == pytest.approx(2.0)
