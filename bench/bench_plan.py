"""`forcemap plan` closed loop in the simulator, against the truth, and the planner's speed.

    python bench/bench_plan.py [--work DIR]

1. river: map a 20-minute lawnmower survey (seed A = 1) from its measurements (simulator bytes -> the
   daemon's pipeline -> MCAP -> export -> fit), plan the lawnmower, fly the original and the planned
   waypoint files with seed B = 2, score both on the intended lines with the true track;
   river-gusts: the same, flown on a gusty day (the `gusts` effect: the wind depends on the seed);
2. lake: the same; the plan should change almost nothing and lose nothing;
3. wrong map: plan on a day of lower discharge (current x 0.6), fly on a dam-release day (discharge
   rising from x 1.0 to x 1.6 over the run);
4. speed: plan a 3-hour mission (the lawnmower 16 times over) from the river survey's maps.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # `bench.*` when run as a script

from bench.closed_loop import fly, low_discharge_scenario, plan_files, survey

SEED_A, SEED_B = 1, 2


def row(name: str, f) -> str:  # type: ignore[no-untyped-def]
    s = f.summary
    te = f.turn_errors
    turns = f"{te.min():.1f}-{te.max():.1f}" if len(te) else "-"
    return (
        f"| {name} | {s['p95_worst_line']:.2f} | {s['miss']:.1f} | {s['coverage']:.1%} | {turns} "
        f"| {f.duration_s:.0f} |"
    )


def closed_loop(
    work: Path, scenario: str, map_scenario: str, effects: list[str], tag: str
) -> list[str]:
    table = survey(map_scenario, SEED_A, work / f"survey-{Path(map_scenario).stem}")
    t0 = time.perf_counter()
    result, orig, planned = plan_files(
        table,
        "lawnmower",
        work / f"plan-{tag}",
        "river" if scenario.startswith("river") or scenario.endswith(".toml") else scenario,
    )
    t_plan = time.perf_counter() - t0
    dur = 1.5 * max(result.original.track.duration, result.planned.track.duration) + 120
    fo = fly(orig, scenario, SEED_B, effects, dur)
    fp = fly(planned, scenario, SEED_B, effects, dur)
    pred_o, pred_p = result.original.to_json(), result.planned.to_json()
    print(
        f"## {tag}: map from {Path(map_scenario).stem} (seed {SEED_A}), flown in {scenario} {effects} (seed {SEED_B})"
    )
    print(f"planning took {t_plan:.1f} s (maps from the workspace's fits, fitted first if missing)")
    print(
        "| mission | p95 worst line m | worst miss m | coverage (3 m) | downstream turn errors m | time s |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    print(row("original, flown", fo))
    print(row("planned, flown", fp))
    print(
        f"| original, predicted | {pred_o['p95_worst_line']:.2f} | {pred_o['miss']:.1f} | {pred_o['coverage']:.1%} | | {pred_o['duration_s']:.0f} |"
    )
    print(
        f"| planned, predicted | {pred_p['p95_worst_line']:.2f} | {pred_p['miss']:.1f} | {pred_p['coverage']:.1%} | | {pred_p['duration_s']:.0f} |"
    )
    print(
        f"map uncertainty of the current: {result.current_scale_sd:.1%}; sensitivity: "
        + "; ".join(
            f"{k}: p95 {v['p95_worst_line']:.2f} m, coverage {v['coverage']:.1%}"
            for k, v in result.sensitivity.items()
        )
    )
    print()
    return [fo, fp, result]


def speed(work: Path) -> None:
    from forcemap.host.plan.boat_model import BoatModel
    from forcemap.host.plan.maps import survey_maps
    from forcemap.host.plan.mission_io import read_mission
    from forcemap.host.plan.planner import plan_mission
    from forcemap.host.vessel.geodesy import LocalFrame
    from forcemap.host.workbench.survey.table import load_survey

    table = survey("river", SEED_A, work / "survey-river")
    m = read_mission("lawnmower", "river")
    sv = load_survey(table)
    frame = LocalFrame(sv.lat0, sv.lon0)
    one = frame.points_to_local(m.latlon)
    passes = [one if k % 2 == 0 else one[::-1] for k in range(16)]
    wps = np.concatenate(passes)
    lines = np.concatenate(
        [
            frame.points_to_local(m.lines_latlon)
            if k % 2 == 0
            else frame.points_to_local(m.lines_latlon)[::-1, ::-1]
            for k in range(16)
        ]
    )
    lo, hi = wps.min(axis=0) - 120.0, wps.max(axis=0) + 120.0
    t0, c0 = time.perf_counter(), time.process_time()
    maps = survey_maps(table, sv, (lo[0], hi[0], lo[1], hi[1]), progress=False)
    t_maps, c_maps = time.perf_counter() - t0, time.process_time() - c0
    t0, c0 = time.perf_counter(), time.process_time()
    result = plan_mission(wps, None, lines, maps, BoatModel())
    t_plan, c_plan = time.perf_counter() - t0, time.process_time() - c0
    print("## speed: a 3-hour mission")
    print(
        f"{len(lines)} lines, original {result.original.track.duration / 3600:.2f} h predicted, planned "
        f"{result.planned.track.duration / 3600:.2f} h; maps {t_maps:.1f} s wall ({c_maps:.1f} s CPU), planning (predict, adjust, "
        f"sensitivity) {t_plan:.1f} s wall, {c_plan:.1f} s CPU; total {t_maps + t_plan:.1f} s wall"
    )
    with open("/proc/loadavg") as f:
        print(f"load average while measuring: {f.read().split()[0]} on {os.cpu_count()} cores")


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument(
        "--work", type=Path, help="folder for the surveys and plans (default: a temporary one)"
    )
    ap.add_argument("--only", choices=("river", "gusts", "lake", "wrong", "speed"))
    args = ap.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="bench_plan-"))
    print(f"work folder {work}", file=sys.stderr)
    if args.only in (None, "river"):
        closed_loop(work, "river", "river", [], "river")
    if args.only in (None, "gusts"):
        # the same map and plan, flown on a day with seeded gusts: seed B now changes the world too
        closed_loop(work, "river", "river", ["gusts"], "river-gusts")
    if args.only in (None, "lake"):
        closed_loop(work, "lake", "lake", [], "lake")
    if args.only in (None, "wrong"):
        low = low_discharge_scenario(work)
        closed_loop(work, "river", str(low), ["dam_release"], "wrong-map")
    if args.only in (None, "speed"):
        speed(work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
