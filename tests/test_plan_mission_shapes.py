"""The missions people fly (issue 31): survey lines recognised from a mission's own shape, QGC .plan files
in and out, line ends and turns from the boat's progress along the line, and a decision that misses its
turn says why.

The missions are bench/mission_shapes.py's: the simulator's river lawnmower laid out as Mission Planner
and QGC write a survey grid (plain, lead-in and overshoot points, lines given in the other direction,
every leg given as a line, DO_CHANGE_SPEED and camera items), each as a WPL 110 file and as a .plan
with a survey ComplexItem. The flights here are offline, on virtual time.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.plan import line_progress as lp
from forcemap.host.plan.boat_model import BoatModel
from forcemap.host.plan.inflight import Replanner
from forcemap.host.plan.mission_io import read_mission, survey_lines
from forcemap.host.plan.service import apply
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel import qgc_plan
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel import waypoints as wp
from forcemap.host.vessel.geodesy import LocalFrame

from bench.mission_shapes import SHAPES, USER_SPEED, shape, write
from tests.test_plan_inflight import provider

SCEN = sc.load("river")
GEO = LocalFrame(SCEN.lat0, SCEN.lon0)


def local(lines_ll: np.ndarray) -> np.ndarray:
    return GEO.points_to_local(lines_ll)


def same_lines(a: np.ndarray, b: np.ndarray, tol: float = 0.5) -> bool:
    """The same segments, each in either direction, in any order."""
    if a.shape != b.shape:
        return False
    left = [ln for ln in b]
    for ln in a:
        k = next((i for i, m in enumerate(left)
                  if np.abs(m - ln).max() < tol or np.abs(m[::-1] - ln).max() < tol), None)  # fmt: skip
        if k is None:
            return False
        left.pop(k)
    return True


# ---- the survey lines, from the mission itself or as given -----------------------------------------
@pytest.mark.parametrize("name", ["plain", "lead_in", "do_items"])
def test_survey_lines_are_the_long_parallel_legs(tmp_path: Path, name: str) -> None:
    wpl, plan = write(name, tmp_path)
    survey = shape(name)[1]
    m = read_mission(str(wpl))
    got = local(m.lines_latlon)
    # five lines of 460 m, all parallel: not the 22.5 m cross legs, nor the lead-in and overshoot legs
    assert same_lines(got, survey)
    lengths = np.hypot(*(got[:, 1] - got[:, 0]).T)
    assert np.all(lengths > 450.0)
    # the .plan gives them explicitly: the survey's transects
    assert same_lines(local(read_mission(str(plan)).lines_latlon), survey)


def test_a_square_keeps_all_its_sides_and_a_wide_grid_not_its_connectors() -> None:
    square = np.array([[-30, -30], [30, -30], [30, 30], [-30, 30], [-30, -30.0]])
    assert len(survey_lines(square)) == 4
    # 100 m lines 50 m apart: the connectors are long, but across the lines and fewer metres in all
    grid = np.array([[0, 0], [100, 0], [100, 50], [0, 50], [0, 100], [100, 100.0]])
    lines = survey_lines(grid)
    assert len(lines) == 3 and np.all(lines[:, 0, 1] == lines[:, 1, 1])


def test_a_sidecar_of_every_leg_is_not_taken_for_given_lines(tmp_path: Path) -> None:
    """`sim -o` writes mission.json with every leg when the mission has no lines of its own; a mission
    read from the folder recognises its five survey lines instead of taking nine."""
    m = ms.load("lawnmower", SCEN)
    (tmp_path / "m.json").write_text(json.dumps(ms.to_json(m, GEO)))
    ms.save_waypoints(tmp_path / "m.waypoints", m, GEO)
    assert json.loads((tmp_path / "m.json").read_text())["lines_given"] is False
    assert len(read_mission(str(tmp_path / "m.waypoints")).lines_latlon) == 5


# ---- QGC .plan ------------------------------------------------------------------------------------
def test_plan_survey_is_read_through_its_generated_items_and_written_back_simple(
    tmp_path: Path,
) -> None:
    items = shape("do_items")[0]
    _, plan = write("do_items", tmp_path)
    doc = json.loads(plan.read_text())
    assert [i["type"] for i in doc["mission"]["items"]] == ["SimpleItem", "ComplexItem"]
    home, got, lines, _ = qgc_plan.read_plan(plan)
    assert [home, *got] == items and lines is not None and len(lines) == 5
    out = tmp_path / "out.plan"
    qgc_plan.write_plan(out, home, got, doc)
    back = json.loads(out.read_text())
    assert {i["type"] for i in back["mission"]["items"]} == {"SimpleItem"}
    assert [i["doJumpId"] for i in back["mission"]["items"]] == list(range(1, len(got) + 1))
    assert all(len(i["params"]) == 7 for i in back["mission"]["items"])
    # every other field of the file as it was
    for key in ("fileType", "groundStation", "version", "geoFence", "rallyPoints"):
        assert back[key] == doc[key]
    for key in ("cruiseSpeed", "firmwareType", "hoverSpeed", "plannedHomePosition", "vehicleType"):
        assert back["mission"][key] == doc["mission"][key]
    assert qgc_plan.read_plan(out)[1] == got


def test_bad_plan_files_are_one_clear_line(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    from forcemap.host.cli import main

    for text, words in (
        ("{not json", "not a QGC .plan"),
        ('{"fileType": "Plan", "mission": {"items": []}}', "no mission items"),
        ('{"fileType": "Plan", "mission": {"items": [{"params": [0]}]}}', "malformed"),
    ):
        p = tmp_path / "bad.plan"
        p.write_text(text)
        assert (
            main(["sim", "--mission", str(p), "--duration", "10s", "-o", str(tmp_path / "o")]) == 2
        )
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err


def test_sim_flies_a_plan_and_serves_its_items(tmp_path: Path) -> None:
    """`sim --mission X.plan`: the autopilot holds the file's items, camera and speed items too."""
    from forcemap.sim_devices.engine import Simulation

    _, plan = write("do_items", tmp_path)
    m = ms.load(str(plan), SCEN)
    sim = Simulation("river", m, [], seed=1, instruments=False)
    sim.start(60.0, lambda *a: None)
    assert sim.autopilot.uplink.accepted == shape("do_items")[0]
    sim.advance(60.0)
    assert sim.current_seq() == 4  # the first line's end: items 1 speed, 2 start, 3 camera, 4 end


# ---- line ends and turns from the boat's progress --------------------------------------------------
def zigzag() -> tuple[list[wp.Item], np.ndarray]:
    """Three 400 m lines that share their ends (no cross legs): A-B, B-C, C-D."""
    xy = np.array([[-200.0, -40.0], [200.0, -20.0], [-200.0, 0.0], [200.0, 20.0]])
    items = [wp.waypoint(*GEO.to_latlon(*xy[0]))] + [wp.waypoint(*GEO.to_latlon(*p)) for p in xy]
    return items, np.stack([xy[:-1], xy[1:]], axis=1)


def test_lines_sharing_a_waypoint_end_at_it_and_the_turn_ends_on_the_next_line() -> None:
    items, lines = zigzag()
    # a current across the lines (1 m/s north): worth replanning
    rp = Replanner(
        items, GEO.points_to_latlon(lines), GEO, BoatModel(), provider(0.0, 1.0), lead_s=10.0
    )
    assert rp.line_seqs == [(1, 2), (2, 3), (3, 4)]
    (a, b), u = lines[0], (lines[0][1] - lines[0][0]) / np.hypot(*(lines[0][1] - lines[0][0]))
    # mid-line: nothing; 100 m before the end (more than 10 s at cruise): nothing
    for along, t in ((200.0, 100.0), (300.0, 130.0)):
        assert rp.position(*GEO.to_latlon(*(a + along * u)), t) is None
    assert rp.mission_current(2, 131.0) is None
    # 30 m before the end (under 10 s at 3.5 m/s): the decision for the turn at B, planned from B
    d = rp.position(*GEO.to_latlon(*(b - 30.0 * u)), 140.0)
    assert d is not None and d.line_done == 0 and d.items is not None and d.keep_seq == 2
    assert not rp.line_over(d) and not rp.turn_missed(d)
    # at B, MISSION_CURRENT goes for C at once: the line is over, the turn is not (the boat is at B)
    rp.position(*GEO.to_latlon(*b), 150.0)
    rp.mission_current(3, 150.0)
    assert rp.line_over(d) and rp.still_in_turn(d)
    # the item kept is B itself (already flown): the new waypoints replace C and what follows
    rp.finish(d)
    assert d.first_seq == 3 and d.items[:3] == items[:3]
    # 12 m along B-C: the turn is over, and a decision applied now is late, with its timings
    c = lines[1][1]
    v = (c - b) / np.hypot(*(c - b))
    rp.position(*GEO.to_latlon(*(b + 12.0 * v)), 158.0)
    assert rp.turn_missed(d) and rp.turn_end_t[0] == 158.0
    apply(rp, d, object(), lambda: 0.0)
    assert not d.uploaded and d.late and not d.refused and d.turn_end_t == 158.0
    assert "decided at t=140.0 s" in d.reason and "turn ended at t=158.0 s" in d.reason
    assert "CPU" in d.reason and "next turn" in d.reason
    # ... and the next turn gets its own decision
    d2 = rp.position(*GEO.to_latlon(*(c - 20.0 * v)), 250.0)
    assert d2 is not None and d2.line_done == 1 and not d2.late


def test_lead_in_and_overshoot_points_are_turns_and_reversed_lines_are_flown_as_flown(
    tmp_path: Path,
) -> None:
    items, survey, _ = shape("lead_in")
    m = read_mission(str(write("lead_in", tmp_path)[0]))
    rp = Replanner(items, m.lines_latlon, GEO, BoatModel(), provider(1.5))
    # each line runs from its second item to its third (lead-in before, overshoot after)
    assert rp.line_seqs == [(2, 3), (6, 7), (10, 11), (14, 15), (18, 19)]
    assert np.abs(rp.lines - survey).max() < 0.5
    # the overshoot point is kept as the boat's turn point: planned from there
    assert rp._keep_seq(0) == 4
    items, survey, given = shape("reversed")
    assert given is not None and np.all(given[:, 1, 0] > given[:, 0, 0])  # all given eastward
    rp = Replanner(items, GEO.points_to_latlon(given), GEO, BoatModel(), provider(1.5))
    assert np.abs(rp.lines - survey).max() < 0.5  # oriented as the mission flies them
    assert rp.line_seqs == [(1, 2), (3, 4), (5, 6), (7, 8), (9, 10)]


def test_line_end_by_position_without_mission_current() -> None:
    line = np.array([[0.0, 0.0], [100.0, 0.0]])
    assert not lp.line_ended(np.array([90.0, 1.0]), 2, line, (1, 2))
    assert lp.line_ended(np.array([98.5, 1.0]), 2, line, (1, 2))
    assert not lp.line_ended(np.array([98.5, 40.0]), 2, line, (1, 2))  # not on it
    assert lp.line_ended(np.array([50.0, 0.0]), 3, line, (1, 2))  # MISSION_CURRENT past its end
    assert lp.to_go(np.array([60.0, 2.0]), 2, line, (1, 2)) == pytest.approx(40.0)


# ---- every shape flown with --replan, DO_ items read back after every upload -----------------------
def mav(it: wp.Item) -> tuple:
    """An item as MISSION_ITEM_INT carries it: positions to 1e-7 degree, params as float32."""
    return (it.command, it.frame, it.lat_e7, it.lon_e7, tuple(np.float32(p) for p in it.params))


def camera_items(items: list[wp.Item]) -> list[tuple]:
    return [mav(i) for i in items if i.command not in (wp.NAV_WAYPOINT, wp.DO_CHANGE_SPEED)]


@pytest.mark.slow
@pytest.mark.parametrize("name", SHAPES)
@pytest.mark.parametrize("kind", ["waypoints", "plan"])
def test_every_shape_replans_in_its_turns_and_keeps_the_users_items(
    tmp_path: Path, name: str, kind: str
) -> None:
    from forcemap.host.plan.upload import download

    from bench.inflight_loop import fly

    path = write(name, tmp_path)[0 if kind == "waypoints" else 1]
    home, items = ms.read_items(path)
    original = [home, *items]  # as the file has them (a WPL keeps six decimals of a degree)
    readbacks: list[list[wp.Item]] = []
    run = fly("river", 2, provider=provider(1.5, 0.5), mission_file=str(path), judge=shape(name)[1],
              duration_s=900.0, on_upload=lambda link: readbacks.append(download(link)))  # fmt: skip
    # one decision per turn between the five survey lines, each in its turn, all accepted
    assert len(run.decisions) == 4
    assert not any(d.late or d.refused for d in run.decisions), [d.reason for d in run.decisions]
    assert run.uploads >= 1 and len(readbacks) == run.uploads
    user_speed = any(i.command == wp.DO_CHANGE_SPEED for i in original)
    for got in readbacks:
        # the camera items come back as they were, in their order, each after a waypoint
        assert camera_items(got) == camera_items(original)
        # the user's speed item is where it was, and every leg the planner does not speed up (it
        # sets a downstream leg's ground speed above the cruise) is flown at the user's speed
        assert mav(got[1]) == mav(original[1])
        # one overrun after the last line, the plan's own (an earlier plan's is not left behind)
        (a, b), ll = shape(name)[1][-1], wp.nav_points(got[1:])[0]
        past = [lp.along_across(p, a, b) for p in GEO.points_to_local(ll)]
        assert sum(al > ln + 1.0 and abs(ac) < 5.0 for al, ac, ln in past) == 1
        speeds = wp.nav_points(got[1:])[1]
        if user_speed:
            user = np.isclose(speeds, USER_SPEED, atol=1e-6)
            assert np.all(user | (speeds > USER_SPEED + 0.25)), speeds
    # the flown lines are all there
    assert all(s["coverage"] > 0.9 for s in run.lines)


# ---- the counts in `log info` and the report ---------------------------------------------------------
def test_decisions_are_counted_made_uploaded_late_refused() -> None:
    from forcemap.host.log.plan_records import describe_counts, replan_counts
    from forcemap.host.report.mission_section import replan_section

    recs = [
        {"line_done": 0, "uploaded": False, "late": True, "reason": "late: decided at t=1.0 s"},
        {"line_done": 1, "uploaded": True, "reason": "upload"},
        {"line_done": 2, "uploaded": False, "refused": True, "reason": "upload failed"},
        {"line_done": 3, "uploaded": False, "reason": "kept"},
    ]
    assert replan_counts(recs) == {"made": 4, "uploaded": 1, "late": 1, "refused": 1}
    text = describe_counts(recs)
    assert text == "4 decisions made, 1 uploaded, 1 late, 1 refused"
    assert text in "\n".join(replan_section(recs))


@pytest.mark.slow
def test_plan_reads_a_plan_and_writes_one_back(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """`forcemap plan TABLE --mission X.plan`: PLANNED.plan beside PLANNED.waypoints, the same items,
    every one a SimpleItem, and the input's other fields kept."""
    from forcemap.host.cli import main
    from forcemap.sim_devices.offline import make_survey

    table = make_survey("river", [], 3, 240.0, tmp_path / "survey")
    _, plan = write("plain", tmp_path)
    out = tmp_path / "planned"
    assert main(["plan", str(table), "--mission", str(plan), "-o", str(out), "--quiet"]) == 0
    written = json.loads((tmp_path / "planned.plan").read_text())
    given = json.loads(plan.read_text())
    assert {i["type"] for i in written["mission"]["items"]} == {"SimpleItem"}
    for key in ("groundStation", "geoFence", "rallyPoints"):
        assert written[key] == given[key]
    assert written["mission"]["cruiseSpeed"] == given["mission"]["cruiseSpeed"]
    _, from_plan, _, _ = qgc_plan.read_plan(tmp_path / "planned.plan")
    from_wpl = wp.read_wpl(tmp_path / "planned.waypoints")[1]  # six decimals of a degree
    assert [i.command for i in from_plan] == [i.command for i in from_wpl]
    assert all(abs(a.lat - b.lat) < 1e-6 and abs(a.lon - b.lon) < 1e-6 and a.params == b.params
               for a, b in zip(from_plan, from_wpl, strict=True))  # fmt: skip
