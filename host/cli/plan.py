"""`forcemap plan`: predict a waypoint mission through the mapped current and wind, and adjust it to hold its lines."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from forcemap.host.cli.common import (
    add_boat,
    add_json,
    add_keep_outliers,
    add_output,
    add_quiet,
    add_reference_current,
    add_table,
    check_json_output,
    human,
    reference_of,
    teach,
    write_json,
)

EPILOG = """\
The maps are the survey's latest fits of current_speed and wind_speed (`forcemap fit`; fitted first if
there are none). The boat model is the simulator's Jetyak with a Rover-like autopilot (ground-speed
loop, line-of-sight guidance); --boat BOAT.toml overrides it:
  [boat]        cruise_speed, max_speed (through water), turn_rate_deg_s
  [hull]        any BoatParams field     [controller]  any Gains field (steer_kp, lookahead_m, ...)

The adjusted mission keeps the intended lines (in PLANNED.json and PLANNED.toml) and adds run-in and
overrun waypoints, moves turn points against the predicted drift, flies the first line upstream and
sets the speed per leg (DO_CHANGE_SPEED). Docs: docs/PLAN.md.

examples:
  forcemap plan survey.csv --mission lawnmower -o planned             # simulator mission by name
  forcemap plan survey.csv --mission survey.waypoints -o planned      # Mission Planner / QGC file
  forcemap plan survey.csv --mission survey.plan -o planned           # QGC .plan: also planned.plan
  forcemap plan logs/run-1.mcap --mission my.toml --boat boat.toml -o planned --json -
  forcemap plan survey.csv --mission survey.waypoints -o planned --upload /dev/ttyACM0,115200
  forcemap plan survey.csv --mission survey.waypoints -o planned --start 2026-06-02T23:00Z

--start (default now) is when the mission is flown: a current fitted with a tide or a seiche term
(`forcemap fit --effects tide`) is predicted for when the boat will be on each line.

writes PLANNED.waypoints (QGC WPL 110: load it in Mission Planner or QGroundControl), PLANNED.toml
(`forcemap sim --mission PLANNED.toml`) and PLANNED.json (waypoints, intended lines, the prediction);
from a QGC .plan also PLANNED.plan (every item a SimpleItem, the file's other fields kept);
-o FOLDER/ (an existing folder) names them FOLDER/MISSION-planned.*. With --json - stdout carries only
the JSON (the table goes to stderr).
"""

MARGIN_M = 120.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    teach(parser, EPILOG)
    add_table(parser, several=True)
    parser.add_argument(
        "--mission",
        required=True,
        help="QGC WPL 110 file (.waypoints), QGC .plan, simulator mission TOML, or a built-in "
        "mission name",
    )
    add_output(
        parser, "PLANNED: writes PLANNED.waypoints, PLANNED.toml, PLANNED.json; an existing folder "
        "gets them named like the mission (MISSION-planned.*)", required=True,
        type=Path, metavar="PLANNED",
    )  # fmt: skip
    add_boat(parser, "TOML overriding the boat and controller model", old_config=False)
    parser.add_argument(
        "--scenario",
        default="river",
        help="where a simulator mission in local metres is laid out (default river)",
    )
    parser.add_argument(
        "--upload", metavar="PORT[,BAUD]", help="send the adjusted mission over MAVLink"
    )
    add_json(parser, "the per-line prediction")
    add_quiet(parser)
    parser.add_argument(
        "--season",
        type=Path,
        metavar="SEASON_DIR",
        help="a `forcemap season` of this river: say how old the map is and what that costs",
    )
    parser.add_argument(
        "--start",
        "--at",
        dest="start",
        metavar="TIME",
        help="when the mission starts: ISO 8601 with its zone (2026-06-02T14:00Z), UNIX time, "
        "a date (its 00:00 UTC) or now (the default: a mission flown as soon as it is uploaded). A "
        "current with a tide or a seiche term is predicted for when the boat is on each line; "
        "with --season, the map's age is counted to it",
    )
    add_keep_outliers(parser)
    add_reference_current(parser)


def print_table(result, out) -> None:  # type: ignore[no-untyped-def]
    o, p = result.original, result.planned

    def print(line: str) -> None:  # noqa: A001 - the table goes where the human text goes
        out.write(line + "\n")

    print("per intended line (predicted): original -> planned")
    print(" line  length   p95 m          worst m        coverage         time s      no headway")
    for i, (a, b) in enumerate(zip(o.scores, p.scores, strict=True)):
        nh = result.no_headway[i]
        print(
            f" {i:4d} {b.length:6.0f}  {a.p95:5.1f} -> {b.p95:4.1f}  {a.miss:5.1f} -> {b.miss:4.1f}"
            f"  {a.coverage:6.1%} -> {b.coverage:6.1%}  {a.time_s:5.0f} -> {b.time_s:4.0f}"
            f"  {'none' if not nh else ', '.join(f'{s:.0f}-{e:.0f} m' for s, e in nh)}"
        )
    print(
        f"mission time {o.track.duration:.0f} s -> {p.track.duration:.0f} s; "
        f"map uncertainty of the current: {result.current_scale_sd:.1%} of its speed (1 sd along the "
        f"lines: the larger of its predictive sd and its blocked-CV RMSE, {result.current_cv_rmse:.3g} m/s)"
    )
    print("how the planned mission's prediction depends on the map:")
    for name, s in result.sensitivity.items():
        what = name.replace("_x", " x ")
        if name.startswith("discharge"):
            what = f"the current {name.split('_x')[1]} x the map's (a higher-discharge day)"
        print(
            f"  {what}: worst-line p95 {s['p95_worst_line']:.2f} m, "
            f"coverage {s['coverage']:.1%}, time {s['duration_s']:.0f} s"
        )
    if result.unchanged:
        print("the mission already holds its lines in the mapped current: written unchanged")
    for tr, what in ((o.track, "original"), (p.track, "planned")):
        if tr.stuck_at is not None:
            print(f"the {what} mission makes no headway toward waypoint {tr.stuck_at}")


def mission_start(args: argparse.Namespace) -> float:
    """--start as UNIX seconds (now by default); a bad one is one line and exit 2."""
    from forcemap.host.workbench.survey.at_time import parse_at

    return parse_at(args.start or "now", "--start")


def map_age_note(args: argparse.Namespace, map_time: float) -> str:
    """`--season`: how old the map is when the mission is flown, and how fast maps age on this river."""

    from forcemap.host.errors import CliError
    from forcemap.host.season.staleness import plan_note
    from forcemap.host.workbench.errors import WorkbenchError

    try:
        return plan_note(args.season, map_time, mission_start(args))
    except WorkbenchError as e:
        raise CliError(str(e)) from None


def adjusting(progress: bool):  # type: ignore[no-untyped-def]
    """The adjuster's progress callback: one line per prediction, with the time so far."""
    t0 = time.perf_counter()

    def step(i: int, n: int) -> None:
        if progress:
            print(
                f"adjusting: prediction {i} of {n} ({time.perf_counter() - t0:.1f} s)",
                file=sys.stderr,
            )

    return step


def run(args: argparse.Namespace) -> int:
    from forcemap.host.errors import CliError
    from forcemap.host.outputs import check_output
    from forcemap.host.plan.boat_model import load_boat
    from forcemap.host.plan.maps import survey_maps
    from forcemap.host.plan.mission_io import output_paths, read_mission, write_outputs
    from forcemap.host.plan.planner import plan_mission
    from forcemap.host.plan.predict import longest_s
    from forcemap.host.plan.workspace_io import save_plan
    from forcemap.host.vessel.geodesy import LocalFrame
    from forcemap.host.workbench.errors import WorkbenchError
    from forcemap.host.workbench.survey.reference import with_reference
    from forcemap.host.workbench.survey.several import load_surveys
    from forcemap.host.workbench.terms.time_terms import iso

    progress = not args.quiet
    if args.output.is_dir():  # a folder: the three files named like the mission
        args.output = args.output / f"{Path(args.mission).stem}-planned"
    from forcemap.host.vessel.qgc_plan import is_plan

    for path in output_paths(args.output, plan=is_plan(args.mission)):
        check_output(path, [args.table, args.mission], args.force)
    check_json_output(args, [args.table, args.mission])
    if not args.table.exists():
        raise CliError(f"no such table {args.table}")
    boat = load_boat(args.boat)
    start = mission_start(args)
    mission = read_mission(args.mission, args.scenario)
    try:
        survey = load_surveys(args.tables, keep_outliers=args.keep_outliers)
        with_reference(survey, reference_of(args))
        age_note = map_age_note(args, float(survey.columns["t"].max())) if args.season else None
        frame = LocalFrame(survey.lat0, survey.lon0)
        wps = frame.points_to_local(mission.latlon)
        lines = frame.points_to_local(mission.lines_latlon)
        lo, hi = wps.min(axis=0) - MARGIN_M, wps.max(axis=0) + MARGIN_M
        span = 1.5 * longest_s(wps, boat)  # run-ins and overruns lengthen the adjusted mission
        maps = survey_maps(args.table, survey, (lo[0], hi[0], lo[1], hi[1]), progress, start, span)
    except WorkbenchError as e:
        raise CliError(str(e)) from e
    for n in maps.notes:
        print(f"note: {n}", file=sys.stderr)
    result = plan_mission(wps, mission.speeds, lines, maps, boat, adjusting(progress))
    out = human(args)
    print(f"boat: {boat.describe()}\nmission start: {iso(start)}", file=out)
    if age_note:
        print(age_note, file=out)
    print_table(result, out)
    report = result.to_json()
    report["start"] = iso(start)
    if age_note:
        report["map_age"] = age_note
    plan = result.planned.plan
    paths = write_outputs(
        args.output,
        frame.points_to_latlon(plan.wps),
        plan.speeds,
        frame.points_to_latlon(plan.lines),
        report,
        f"{mission.name} adjusted by forcemap plan for {args.table.name}",
        mission.plan_doc,
    )
    save_plan(args.table, mission.name, result, maps)
    for p in paths:
        print(f"wrote {p}", file=out)
    write_json(args.json, report, indent=1)
    if args.upload:
        from forcemap.host.plan.upload import upload_file

        n = upload_file(args.upload, paths[0], progress=progress)
        print(
            f"uploaded {n} mission items to {args.upload}; the vehicle acknowledged them", file=out
        )
    return 0
