"""The planner on fields it is given directly: no headway, still water, and speed for a following current."""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.plan.boat_model import BoatModel
from forcemap.host.plan.maps import Field, Maps
from forcemap.host.plan.planner import no_headway, plan_mission
from forcemap.host.plan.predict import predict_track


def uniform(east: float, north: float = 0.0) -> Maps:
    """The same current everywhere (its map known to 0.05 m/s), no wind."""
    e, n = np.full((3, 3), east), np.full((3, 3), north)
    z = np.zeros((3, 3))
    current = Field(-1000.0, -1000.0, 1000.0, e, n, z + 0.05, z + 0.05, ["test"])
    return Maps(current, Field.still(), 0.0, 0.0)


LAWN = np.array([[200.0, 0.0], [-200.0, 0.0], [-200.0, 25.0], [200.0, 25.0]])
LINES = np.array([[[200.0, 0.0], [-200.0, 0.0]], [[-200.0, 25.0], [200.0, 25.0]]])


def test_no_headway_against_a_current_faster_than_the_boat() -> None:
    slow = BoatModel().with_max_speed(2.0)
    maps = uniform(2.5)
    runs = no_headway(LINES, maps, slow)
    assert runs[0] == [(0.0, 400.0)] and runs[1] == []  # upstream: all of it; downstream: none
    tr = predict_track(LAWN, None, maps, slow, t_max=900.0)
    assert tr.stuck_at == 1  # it never reaches the end of the upstream line
    assert tr.x.min() > 150.0  # and is swept back toward the east


def test_still_water_mission_is_kept_unchanged() -> None:
    res = plan_mission(LAWN, None, LINES, uniform(0.0), BoatModel())
    assert res.unchanged and res.planned is res.original
    assert all(s.coverage >= 0.95 for s in res.planned.scores)


def test_following_current_gets_speed_and_run_ins() -> None:
    boat = BoatModel()
    # the mission as given starts with its line flown downstream
    wps = np.array([[-200.0, 25.0], [200.0, 25.0], [200.0, 0.0], [-200.0, 0.0]])
    # a 2.5 m/s current with a 0.4 m/s cross-flow: downstream at 1 m/s through the water the boat crabs
    res = plan_mission(wps, None, LINES[::-1].copy(), uniform(2.5, 0.4), boat)
    assert min(s.coverage for s in res.original.scores) < 0.95
    assert not res.unchanged
    plan = res.planned.plan
    # the first line is now flown against the flow (west), and the downstream legs are given the
    # ground speed that keeps the calm-water cruise through the water
    first = plan.lines[0]
    assert first[1][0] < first[0][0]
    down = [
        plan.speeds[k]
        for k in range(1, len(plan.wps))
        if plan.wps[k, 0] - plan.wps[k - 1, 0] > 20.0
    ]
    assert down and all(s == pytest.approx(boat.cruise_speed + 2.5, abs=0.05) for s in down)
    assert len(plan.wps) > len(wps) + 2  # run-ins and overruns
    assert all(s.coverage >= 0.95 and s.p95 <= 3.0 for s in res.planned.scores)
