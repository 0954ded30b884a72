"""The survey missions people fly, written as Mission Planner and QGroundControl write them (issue 31).

Every shape is the simulator's river lawnmower (five survey lines of 460 m, 22.5 m apart; `forcemap sim
--scenario river --mission lawnmower`) as a ground station would lay it out, written by hand here with
the project's own writers: a QGC WPL 110 file (``.waypoints``; Mission Planner's *Save WP File*) and a
QGC ``.plan`` whose survey is a ``ComplexItem`` (complexItemType "survey") with its generated simple
items in ``TransectStyleComplexItem.Items`` and its transects in ``VisualTransectPoints``, as QGC's
Survey pattern saves it.

- ``plain``: the 10 waypoints; each line's last waypoint starts the short cross leg to the next line
  (the grid of Mission Planner's *Survey (Grid)* with no lead-in or overshoot). From the WPL file the
  survey lines are recognised (long parallel legs against short connectors).
- ``every_leg``: the same waypoints with every leg given as an intended line (nine lines, each sharing
  its waypoints with the next): what `forcemap sim -o` wrote beside such a file before issue 31.
- ``lead_in``: a 15 m lead-in point before each line and a 10 m overshoot point after it (Mission
  Planner's *Lead In* and *Overshoot*; QGC's turnaround distance).
- ``reversed``: the plain mission with its lines given all pointing east: lines 2 and 4 are flown
  against the direction they were given in.
- ``do_items``: a DO_CHANGE_SPEED the user set (3.2 m/s ground speed) before the survey, and camera
  triggering (DO_SET_CAM_TRIGG_DIST 5 m after each line's first waypoint, 0 after its last; MP's
  *Cam trigger distance*).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel import qgc_plan
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel import waypoints as wp
from forcemap.host.vessel.geodesy import LocalFrame
from pymavlink.dialects.v20 import ardupilotmega as M

SHAPES = ("plain", "every_leg", "lead_in", "reversed", "do_items")
CAM_TRIGG_DIST = M.MAV_CMD_DO_SET_CAM_TRIGG_DIST
USER_SPEED = 3.2
LEAD_IN_M, OVERSHOOT_M = 15.0, 10.0


def camera(dist: float) -> wp.Item:
    return wp.Item(CAM_TRIGG_DIST, params=(dist, 0.0, 1.0, 0.0), frame=2)


def shape(
    name: str, scenario: str = "river"
) -> tuple[list[wp.Item], np.ndarray, np.ndarray | None]:
    """(mission items, home first; the five survey lines (local m, as flown); the intended lines the
    file gives explicitly (local m) or None: recognised from the mission)."""
    scen = sc.load(scenario)
    geo = LocalFrame(scen.lat0, scen.lon0)
    wps = ms.load("lawnmower", scen).waypoints
    survey = wps.reshape(-1, 2, 2)

    def nav(p: np.ndarray) -> wp.Item:
        lat, lon = geo.to_latlon(p[0], p[1])
        return wp.waypoint(float(lat), float(lon))

    items: list[wp.Item] = []
    given: np.ndarray | None = None
    if name in ("plain", "every_leg", "reversed"):
        items = [nav(p) for p in wps]
        if name == "every_leg":
            given = np.stack([wps[:-1], wps[1:]], axis=1)
        elif name == "reversed":
            given = np.array([ln if ln[1, 0] > ln[0, 0] else ln[::-1] for ln in survey])
    elif name == "lead_in":
        for a, b in survey:
            u = (b - a) / np.hypot(*(b - a))
            items += [nav(a - LEAD_IN_M * u), nav(a), nav(b), nav(b + OVERSHOOT_M * u)]
    elif name == "do_items":
        items = [wp.change_speed(USER_SPEED)]
        for a, b in survey:
            items += [nav(a), camera(5.0), nav(b), camera(0.0)]
    else:
        raise ValueError(f"unknown shape {name!r}; shapes: {', '.join(SHAPES)}")
    home = nav(wps[0])
    return [home, *items], survey, given


def write(name: str, folder: Path, scenario: str = "river") -> tuple[Path, Path]:
    """The shape as NAME.waypoints (with NAME.json beside it when its lines are given) and NAME.plan."""
    items, survey, given = shape(name, scenario)
    scen = sc.load(scenario)
    geo = LocalFrame(scen.lat0, scen.lon0)
    folder.mkdir(parents=True, exist_ok=True)
    wpl, plan = folder / f"{name}.waypoints", folder / f"{name}.plan"
    wp.write_wpl(wpl, items[0], items[1:])
    if given is not None:
        la, lo = geo.to_latlon(given[..., 0], given[..., 1])
        lines = [{"latlon": [[float(la[i, j]), float(lo[i, j])] for j in range(2)]}
                 for i in range(len(given))]  # fmt: skip
        (folder / f"{name}.json").write_text(json.dumps({"lines_given": True, "lines": lines}))
    transects = given if given is not None else survey
    la, lo = geo.to_latlon(transects[..., 0], transects[..., 1])
    visual = [[float(la[i, j]), float(lo[i, j])] for i in range(len(transects)) for j in range(2)]
    doc = plan_with_survey(items, visual)
    plan.write_text(json.dumps(doc, indent=4) + "\n")
    return wpl, plan


def plan_with_survey(items: list[wp.Item], visual: list[list[float]]) -> dict:
    """A QGC .plan: the items before the first waypoint as SimpleItems, then one survey ComplexItem
    whose generated Items are the rest."""
    first = next(k for k, it in enumerate(items[1:], 1) if it.command == wp.NAV_WAYPOINT)
    doc = qgc_plan.plan_document(items[0], items[1:first])
    simple = doc["mission"]["items"]
    generated = [
        qgc_plan.simple_item(it, len(simple) + k + 1) for k, it in enumerate(items[first:])
    ]
    doc["groundStation"] = "QGroundControl"
    doc["mission"]["items"] = simple + [{
        "TransectStyleComplexItem": {
            "CameraCalc": {"AdjustedFootprintFrontal": 5, "AdjustedFootprintSide": 22.5,
                           "CameraName": "Manual (no camera specs)", "DistanceToSurface": 1,
                           "DistanceToSurfaceRelative": True, "version": 1},
            "CameraShots": 0, "CameraTriggerInTurnAround": False, "HoverAndCapture": False,
            "Items": generated, "Refly90Degrees": False, "TurnAroundDistance": 0,
            "VisualTransectPoints": visual, "version": 1,
        },
        "angle": 90, "complexItemType": "survey", "entryLocation": 0,
        "flyAlternateTransects": False, "polygon": [], "splitConcavePolygons": False,
        "type": "ComplexItem", "version": 5,
    }]  # fmt: skip
    doc["geoFence"]["polygons"] = [{"inclusion": True, "polygon": [v[:2] for v in visual[:3]],
                                    "version": 1}]  # fmt: skip
    return doc
