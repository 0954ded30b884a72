"""In-flight replanning: the simulated autopilot behaves like Rover for it, and the replanner's safety rules.

Flights are offline (bench/inflight_loop.py): the simulator's bytes through the daemon's pipeline, the
ground side of the mission protocol talking to the simulated autopilot, virtual time. These use a
uniform current map (cheap) where the map is not what is tested; the closed loop with maps refitted
in flight is in test_plan_inflight_loop.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from forcemap.host.plan.boat_model import BoatModel
from forcemap.host.plan.inflight import MapSnapshot, Replanner
from forcemap.host.plan.maps import Field, Maps
from forcemap.host.plan.upload import download, same_mission
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.sim_devices import modes as md
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.truth import track_arrays
from pymavlink.dialects.v20 import ardupilotmega as M

from bench.inflight_loop import OfflineLink, fly, mission

SHORT_S = 300.0  # two lines and the turn after the second: two decisions


def uniform(east: float, north: float = 0.0) -> Maps:
    z = np.zeros((2, 2))
    f = Field(-1e3, -1e3, 2e3, z + east, z + north, z + 0.05, z + 0.05, ["const"])
    return Maps(f, Field.still(), 0.0, 0.0)


def provider(east: float, north: float = 0.0):  # type: ignore[no-untyped-def]
    return lambda: MapSnapshot(uniform(east, north), 0.0, 1000)


def heard(sim: Simulation, kinds: set[str]) -> list:
    got: list = []
    link = OfflineLink(sim, lambda m: got.append(m) if m.get_type() in kinds else None)
    sim.start(600.0, lambda source, t, data: link.feed(data) if source == "mavlink" else None)
    return got, link  # type: ignore[return-value]


# ---- the simulated autopilot ------------------------------------------------------------------------
def test_scripted_modes_show_in_heartbeat_and_stop_the_mission(tmp_path: Path) -> None:
    text = (Path(sc.__file__).parent / "scenarios" / "river.toml").read_text()
    text += (
        '\n[[operator]]\nat_s = 20.0\nmode = "HOLD"\n\n[[operator]]\nat_s = 40.0\nmode = "AUTO"\n'
    )
    (tmp_path / "r.toml").write_text(text)
    sim = Simulation(str(tmp_path / "r.toml"), mission("river"), [], seed=1)
    got, _ = heard(sim, {"HEARTBEAT"})
    sim.advance(60.0)
    seen = [m.custom_mode for m in got]
    assert md.MODES["HOLD"] in seen and seen[0] == md.AUTO and seen[-1] == md.AUTO
    assert [m for _, m in sim.mode_log] == [md.MODES["HOLD"], md.AUTO]
    # in HOLD the motor is off: no throttle between the switches
    tr = track_arrays(sim.rows, sim.extra)
    hold = (tr["t"] > 21.0) & (tr["t"] < 39.0)
    assert np.all(tr["throttle"][hold] == 0.0) and np.all(tr["throttle"][tr["t"] > 45.0] > 0.0)


def test_new_mission_in_auto_keeps_the_current_item_and_set_current_moves_it() -> None:
    sim = Simulation("river", mission("river"), [], seed=1)
    got, link = heard(sim, {"MISSION_CURRENT"})
    sim.advance(60.0)  # on the first line: going for item 2
    assert sim.current_seq() == 2
    items = download(link)  # the mission protocol's download, as the replanner reads it
    assert len(items) == 11 and same_mission(items, sim.autopilot.uplink.accepted)
    # the same mission with item 4 moved 10 m north: accepted in AUTO, the boat keeps item 2
    new = list(items)
    it = new[4]
    new[4] = type(it)(it.command, it.lat + 10.0 / 111_320.0, it.lon)
    from forcemap.host.plan.upload import Uploader, set_current

    assert Uploader(link, new).run() == 11
    assert sim.current_seq() == 2 and sim.mission.name == "uploaded"
    assert sim.mission.waypoints[3, 1] == pytest.approx(items_y(sim, 4), abs=0.5)
    assert items_y(sim, 4) == pytest.approx(items_y_of(items, sim, 4) + 10.0, abs=0.5)
    set_current(link, 6)
    sim.advance(sim.t + 2.0)
    assert sim.current_seq() == 6 and got[-1].seq == 6


def items_y(sim: Simulation, seq: int) -> float:
    return items_y_of(sim.autopilot.uplink.accepted, sim, seq)


def items_y_of(items: list, sim: Simulation, seq: int) -> float:
    it = items[seq]
    return float(sim.geo.to_local(np.array([it.lat]), np.array([it.lon]))[1][0])


# ---- the replanner's rules -------------------------------------------------------------------------
def test_naked_or_lost_upload_keeps_the_old_mission_and_it_is_flown() -> None:
    for name, setup in (
        ("nak", lambda s: setattr(s.autopilot.uplink, "nak_at", 2)
         or setattr(s.autopilot.uplink, "nak_times", 1000)),
        ("lost", lambda s: setattr(s.autopilot.uplink, "deaf", True)),
    ):  # fmt: skip
        run = fly("river", 2, configure=setup, provider=provider(1.5), duration_s=SHORT_S)
        tried = [d for d in run.decisions if d.items is not None]
        assert len(tried) >= 1, name
        assert run.uploads == 0 and all("upload failed" in d.reason for d in tried), name
        assert run.sim.mission.name == "lawnmower", name  # the autopilot flies its own mission
        # ... and flies it: the second line is held as the original flies it (not left)
        assert run.lines[1]["coverage"] > 0.3 and run.lines[1]["time_s"] > 60.0, name
        assert any("upload failed" in x for x in run.log), name


def test_manual_stops_replanning_until_auto() -> None:
    switched: list[float] = []

    def operator(sim: Simulation, d) -> None:  # type: ignore[no-untyped-def]
        # the operator takes the boat while the first decision is being planned, for 8 s
        if not switched:
            switched.append(sim.t)
            sim.mode_changes = [md.ModeChange(sim.t + 0.5, md.MODES["MANUAL"]),
                                md.ModeChange(sim.t + 8.0, md.AUTO)]  # fmt: skip

    run = fly("river", 2, on_decision=operator, provider=provider(1.5), duration_s=SHORT_S)
    first, second = run.decisions[0], run.decisions[1]
    assert switched and first.items is not None and not first.uploaded
    assert "not sent" in first.reason  # decided in AUTO, but MANUAL came before the upload
    assert not first.late and not first.refused
    assert second.uploaded and second.t_sent is not None and second.t_sent > switched[0] + 8.0
    assert any("mode MANUAL" in x for x in run.log)


def test_turn_points_beyond_the_bound_are_clipped_and_logged() -> None:
    # a map with a current across the lines: the planner moves turn points sideways against it
    run = fly("river", 2, provider=provider(1.5, 0.8), duration_s=SHORT_S, bound_m=1.0)
    d = run.decisions[0]
    assert d.clipped > 0 and d.clipped_max_m > 0.5
    assert any("moved back within the bounds" in x for x in run.log)
    # every waypoint sent is within 1 m across its line (or in the area)
    lines = mission("river").lines[1:]
    for w in d.new_wps:  # type: ignore[union-attr]
        across = [
            abs((b - a)[0] * (w - a)[1] - (b - a)[1] * (w - a)[0]) / np.hypot(*(b - a))
            for a, b in lines
        ]
        assert min(across) <= 1.0 + 1e-6


def test_junk_maps_are_refused_in_one_line() -> None:
    frame = LocalFrame(33.82, -80.85)
    m = mission("river")
    sim = Simulation("river", m, [], seed=1, instruments=False)
    sim.start(10.0, lambda *a: None)
    items = sim.autopilot.uplink.accepted
    for maps, words in (
        (uniform(50.0), "current map reaches 50.0 m/s"),
        (uniform(float("nan")), "current map has values that are not numbers"),
    ):
        log: list[str] = []
        rp = Replanner(items, frame.points_to_latlon(m.lines), frame, BoatModel(),
                       lambda maps=maps: MapSnapshot(maps, 0.0, 10), log=log.append)  # fmt: skip
        rp.position(*frame.points_to_latlon(np.array(m.lines[0, 1])))
        d = rp.mission_current(3, 100.0)
        assert d is not None and d.items is None and words in d.reason
        assert len([x for x in log if words in x]) == 1


def test_no_decision_in_manual_hold_or_rtl_nor_mid_line() -> None:
    frame = LocalFrame(33.82, -80.85)
    m = mission("river")
    sim = Simulation("river", m, [], seed=1, instruments=False)
    sim.start(10.0, lambda *a: None)
    rp = Replanner(sim.autopilot.uplink.accepted, frame.points_to_latlon(m.lines), frame, BoatModel(),
                   provider(1.5))  # fmt: skip
    a, b = m.lines[0]
    rp.position(*frame.points_to_latlon(0.5 * (a + b)))
    assert rp.mission_current(2, 50.0) is None  # mid-line: nothing to decide
    rp.position(*frame.points_to_latlon(np.array(b)))
    for mode in ("MANUAL", "HOLD", "RTL"):
        rp.heartbeat(mode)
        rp.done = -1
        d = rp.mission_current(3, 100.0)
        assert d is not None and d.items is None and f"mode {mode}" in d.reason
    rp.heartbeat("AUTO")
    rp.done = -1
    d = rp.mission_current(3, 100.0)
    assert d is not None and d.items is not None and d.set_current is not None
    assert M.MAV_CMD_NAV_WAYPOINT in {i.command for i in d.items[3:]}


def test_the_live_maps_board_feeds_the_replanner_in_its_own_frame() -> None:
    """With --live the replanner reads the live map process's newest grids (MapBoard), moved from the
    map's local frame into the replanner's."""
    from forcemap.host.live.growing import MapGrid
    from forcemap.host.live.mapproc import MapBoard
    from forcemap.host.plan.refit_maps import BoardMaps

    board = MapBoard()
    provider = BoardMaps(board, 33.82, -80.85)
    assert provider() is None  # no map yet
    ny, nx = 3, 4
    east = np.tile(np.arange(nx, dtype=float), (ny, 1))  # 0, 1, 2, 3 m/s going east, cell by cell
    z = np.zeros((ny, nx))
    f = {"east": east, "north": z, "speed": east, "east_sd": z + 0.1, "north_sd": z + 0.1,
         "speed_sd": z + 0.1}  # fmt: skip
    # the map's origin 100 m east of the replanner's
    lon0 = float(LocalFrame(33.82, -80.85).to_latlon(100.0, 0.0)[1])
    board.put([MapGrid("current", 33.82, lon0, 0.0, 0.0, 10.0, f, 500, 1000.0, 900.0)])
    snap = provider()
    assert snap is not None and snap.samples == 500 and snap.t_data == 1000.0
    # the map's x = 10 m (1 m/s) is the replanner's x = 110 m
    assert snap.maps.current.at(110.0, 0.0)[0] == pytest.approx(1.0, abs=0.02)
    assert snap.maps.current.at(125.0, 0.0)[0] == pytest.approx(2.5, abs=0.02)
    assert snap.maps.wind.at(0.0, 0.0) == (0.0, 0.0)
