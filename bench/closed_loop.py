"""The planner judged against the simulator's truth: map a survey from its measurements, plan, fly, score.

1. ``survey``: the simulator's bytes through the daemon's pipeline into MCAP, exported to a samples table
   (`sim_devices.offline.make_survey`): measured current and wind, never the truth;
2. ``plan_files``: `forcemap plan`'s library path on that table, written as files;
3. ``fly``: the original and the planned waypoint files flown by the simulator (another seed, possibly
   another day), scored on the intended lines with the true track.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from forcemap.host.plan.boat_model import BoatModel
from forcemap.host.plan.maps import survey_maps
from forcemap.host.plan.metrics import distance_to_path, score_lines, summary
from forcemap.host.plan.mission_io import read_mission, write_outputs
from forcemap.host.plan.planner import PlanResult, plan_mission
from forcemap.host.plan.workspace_io import save_plan
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.offline import make_survey

SURVEY_S = 1200.0  # the survey's length: the looping lawnmower over the reach


def survey(scenario: str, seed: int, out: Path, duration_s: float = SURVEY_S) -> Path:
    """A measured samples table of a looping lawnmower survey (reused if already made in ``out``)."""
    table = out / "samples.csv"
    if not table.exists():
        make_survey(scenario, [], seed, duration_s, out)
    return table


def low_discharge_scenario(folder: Path) -> Path:
    """The river with its current x 0.6 (bank 0.6, thalweg 1.5 m/s): a dry day, for mapping with a map
    that will be wrong on the day the mission is flown."""
    text = (Path(sc.__file__).parent / "scenarios" / "river.toml").read_text()
    text = text.replace('name = "river"', 'name = "river_low"')
    text = text.replace("bank = 1.0 ", "bank = 0.6 ").replace("thalweg = 2.5 ", "thalweg = 1.5 ")
    path = folder / "river_low.toml"
    path.write_text(text)
    return path


def plan_files(
    table: Path, mission: str, out: Path, scenario: str, boat: BoatModel | None = None
) -> tuple[PlanResult, Path, Path]:
    """Plan ``mission`` on ``table``; returns the result, the original and the planned waypoint files."""
    from forcemap.host.workbench.survey.table import load_survey

    boat = boat or BoatModel()
    m = read_mission(mission, scenario)
    sv = load_survey(table)
    frame = LocalFrame(sv.lat0, sv.lon0)
    wps, lines = frame.points_to_local(m.latlon), frame.points_to_local(m.lines_latlon)
    lo, hi = wps.min(axis=0) - 120.0, wps.max(axis=0) + 120.0
    maps = survey_maps(table, sv, (lo[0], hi[0], lo[1], hi[1]), progress=False)
    result = plan_mission(wps, m.speeds, lines, maps, boat)
    save_plan(table, m.name, result, maps)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for name, o in (("original", result.original), ("planned", result.planned)):
        paths = write_outputs(
            out / name,
            frame.points_to_latlon(o.plan.wps),
            o.plan.speeds,
            frame.points_to_latlon(result.planned.plan.lines),
            o.to_json(),
            name,
        )
        files.append(paths[0])
    return result, files[0], files[1]


@dataclass
class Flight:
    """A flown track scored on the intended lines."""

    summary: dict
    lines: list
    duration_s: float
    turn_errors: (
        np.ndarray
    )  # Fig. 2: worst distance from the path in the 25 s after each downstream turn


def turn_errors(tr: dict, wps: np.ndarray, flow_deg: float, window_s: float = 25.0) -> np.ndarray:
    """Largest distance from the waypoint path in the ``window_s`` after each waypoint entered downstream."""
    dist = distance_to_path(np.column_stack([tr["x"], tr["y"]]), wps)
    fx, fy = np.sin(np.radians(flow_deg)), np.cos(np.radians(flow_deg))
    out = []
    for i in np.nonzero(np.diff(tr["leg"]) > 0)[0] + 1:
        j = max(i - 100, 0)
        dx, dy = tr["x"][i] - tr["x"][j], tr["y"][i] - tr["y"][j]
        if (dx * fx + dy * fy) / max(np.hypot(dx, dy), 1e-9) >= 0.7:
            out.append(dist[i : i + int(window_s * 10)].max())
    return np.array(out)


def fly(
    waypoints: Path, scenario: str, seed: int, effects: list[str], duration_s: float, boat=None
) -> Flight:  # type: ignore[no-untyped-def]
    """Fly a waypoint file offline and score the true track, until the mission ends, on its intended
    lines (from the FILE.json beside it); ``boat``: (BoatParams, Gains) of the boat flown."""
    sim = Simulation(scenario, str(waypoints), effects, seed=seed, instruments=False,
                     boat_params=boat and boat[0], gains=boat and boat[1])  # fmt: skip
    if sim.mission.lines is None:
        raise ValueError(f"{waypoints} has no intended lines beside it ({waypoints.stem}.json)")
    sim.run(duration_s, lambda *a: None)
    tr = sim.track
    flying = tr["leg"] < len(sim.mission.waypoints) - 1
    keep = {k: v[flying] for k, v in tr.items()}
    sc = score_lines(keep["t"], np.column_stack([keep["x"], keep["y"]]), sim.mission.lines)
    te = turn_errors(keep, sim.mission.waypoints, sim.scenario.flow_dir_deg)
    return Flight(summary(sc), [s.to_json() for s in sc], float(keep["t"][-1]), te)
