"""In-flight replanning against the simulator's truth (docs/PLAN.md, "In flight"): the first survey of
an unmapped river, flown with and without `--replan`, on the planner's boat and on two boats unlike it;
the dam-release day; `plan` between surveys on the unlike boats; and the cost of one decision.

    python -m bench.bench_inflight --work /tmp/inflight [--only loop|boats|dam|between|cost|shapes]

Prints a markdown table per part and writes WORK/inflight.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from bench.inflight_loop import JUDGED_FROM, fly, perturbed

SEEDS = (1, 2)


def row(name: str, r) -> dict:  # type: ignore[no-untyped-def]
    j = r.judged
    per = [f"{s['p95']:.2f}/{s['coverage']:.0%}" for s in r.lines]
    cpu = [d.cpu_s for d in r.decisions if d.new]
    fit = [d.map_cpu_s for d in r.decisions if d.map_samples]
    out = {
        "case": name, "p95_worst_judged": round(j["p95_worst_line"], 2),
        "p95_pooled_judged": round(r.pooled_p95, 2), "coverage_judged": round(j["coverage"], 4),
        "per_line": per, "uploads": r.uploads, "decisions": len(r.decisions),
        "decision_cpu_s_max": round(max(cpu), 2) if cpu else None,
        "map_fit_cpu_s_max": round(max(fit), 2) if fit else None, "duration_s": round(r.duration_s),
        "reasons": [d.reason for d in r.decisions],
    }  # fmt: skip
    print(
        f"| {name} | {out['p95_worst_judged']:.2f} | {out['p95_pooled_judged']:.2f} | "
        f"{out['coverage_judged']:.1%} | {' · '.join(per)} | {r.uploads} | {out['duration_s']} |",
        flush=True,
    )
    return out


def header() -> None:
    print(
        f"| case | p95 worst line m (lines {JUDGED_FROM + 1}+) | p95 pooled m | coverage | "
        "per line p95 m / coverage | uploads | time s |\n|---|---:|---:|---:|---|---:|---:|",
        flush=True,
    )


def loop(out: list) -> None:
    header()
    for seed in SEEDS:
        out.append(row(f"river seed {seed}, no replan", fly("river", seed, replan=False)))
        out.append(row(f"river seed {seed}, --replan", fly("river", seed, replan=True)))


def boats(out: list) -> None:
    header()
    for draw in (1, 2):
        p, g, f = perturbed(draw)
        tag = ", ".join(f"{k} x{v:.2f}" for k, v in f.items())
        for seed in SEEDS:
            for rp in (False, True):
                name = f"boat {draw} ({tag}), seed {seed}, {'--replan' if rp else 'no replan'}"
                out.append(row(name, fly("river", seed, replan=rp, boat=(p, g))))


def dam(out: list) -> None:
    header()
    for seed in SEEDS:
        for rp in (False, True):
            r = fly("river", seed, replan=rp, effects=["dam_release"], duration_s=800.0)
            res = row(f"dam release, seed {seed}, {'--replan' if rp else 'no replan'}", r)
            res["map_current_mean"] = [d.current_mean for d in r.decisions]
            res["map_age_s"] = [d.map_age_s for d in r.decisions]
            out.append(res)


def between(out: list, work: Path) -> None:
    """`plan` between surveys (map on one day, fly the next) on the boats unlike the planner's."""
    from bench.closed_loop import fly as fly_file
    from bench.closed_loop import plan_files, survey

    table = survey("river", 1, work / "survey-river")
    result, orig, planned = plan_files(table, "lawnmower", work / "plan-river", "river")
    dur = 1.5 * max(result.original.track.duration, result.planned.track.duration) + 120
    print("| boat | mission | p95 worst line m | coverage |\n|---|---|---:|---:|")
    for draw in (0, 1, 2):
        boat = perturbed(draw)[:2] if draw else None
        for name, path in (("original", orig), ("planned", planned)):
            f = fly_file(path, "river", 2, [], dur, boat=boat)
            s = f.summary
            print(
                f"| {draw or 'model'} | {name} | {s['p95_worst_line']:.2f} | {s['coverage']:.1%} |"
            )
            out.append({"boat": draw, "mission": name, **{k: float(v) for k, v in s.items()}})


def cost(out: list, work: Path) -> None:
    """One decision on a 20-minute survey's maps: map fitted once (the live map's job), then decide."""
    from forcemap.host.plan.boat_model import BoatModel
    from forcemap.host.plan.inflight import MapSnapshot, Replanner
    from forcemap.host.plan.maps import survey_maps
    from forcemap.host.vessel.geodesy import LocalFrame
    from forcemap.host.workbench.survey.table import load_survey
    from forcemap.sim_devices.engine import Simulation

    from bench.closed_loop import survey
    from bench.inflight_loop import mission

    table = survey("river", 1, work / "survey-river")
    sv = load_survey(table)
    m = mission("river")
    frame = LocalFrame(sv.lat0, sv.lon0)
    sim = Simulation("river", m, [], seed=1, instruments=False)
    sim.start(10.0, lambda *a: None)
    items = sim.autopilot.uplink.accepted
    lines_ll = np.stack(sim.geo.to_latlon(m.lines[..., 0], m.lines[..., 1]), axis=-1)
    lines = frame.points_to_local(lines_ll)
    lo, hi = lines.reshape(-1, 2).min(axis=0) - 120, lines.reshape(-1, 2).max(axis=0) + 120
    maps = survey_maps(table, sv, (lo[0], hi[0], lo[1], hi[1]), progress=False)
    snap = MapSnapshot(maps, 0.0, sv.n)
    times = []
    for _ in range(3):
        rp = Replanner(items, lines_ll, frame, BoatModel(), lambda: snap)
        rp.position(*lines_ll[0, 1])
        c0 = time.process_time()
        d = rp.mission_current(3, 0.0)
        times.append(time.process_time() - c0)
        assert d is not None and d.new
    print(
        f"one decision after line 1 (4 lines left): {min(times):.2f}-{max(times):.2f} s CPU; {d.reason}"
    )
    out.append({"decision_cpu_s": times, "reason": d.reason})
    # a long mission: the lawnmower there and back 4 times (40 lines, about 95 minutes)
    from forcemap.host.vessel import mission as ms

    wps = np.vstack([m.waypoints if k % 2 == 0 else m.waypoints[::-1] for k in range(8)])
    long = ms.Mission("long", "", wps, False, None, wps.reshape(-1, 2, 2))
    sim = Simulation("river", long, [], seed=1, instruments=False)
    sim.start(10.0, lambda *a: None)
    ll = np.stack(sim.geo.to_latlon(long.lines[..., 0], long.lines[..., 1]), axis=-1)
    rp = Replanner(sim.autopilot.uplink.accepted, ll, frame, BoatModel(), lambda: snap)
    rp.position(*ll[0, 1])
    c0 = time.process_time()
    d = rp.mission_current(3, 0.0)
    t_long = time.process_time() - c0
    assert d is not None
    print(
        f"one decision after line 1 of {len(ll)} ({len(ll) - 1} left): {t_long:.2f} s CPU; {d.reason}"
    )
    out.append({"decision_cpu_s_long": t_long, "lines": len(ll), "reason": d.reason})


def shapes(out: list, work: Path) -> None:
    """Every mission shape people fly (bench/mission_shapes.py), as a WPL file and as a QGC .plan, flown
    with --replan on maps refitted in flight; judged on the five survey lines (lines 3-5)."""
    from bench.mission_shapes import SHAPES, shape, write

    header()
    for name in SHAPES:
        for path in write(name, work / "shapes"):
            r = fly("river", 2, replan=True, mission_file=str(path), judge=shape(name)[1])
            res = row(f"{path.name}, --replan", r)
            res["late"] = sum(d.late for d in r.decisions)
            out.append(res)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--work", default="/tmp/inflight")
    ap.add_argument(
        "--only", choices=["loop", "boats", "dam", "between", "cost", "shapes"], action="append"
    )
    a = ap.parse_args()
    work = Path(a.work)
    work.mkdir(parents=True, exist_ok=True)
    parts = a.only or ["loop", "boats", "dam", "between", "cost"]
    res: dict = {}
    for p in parts:
        res[p] = []
        print(f"\n### {p}\n", flush=True)
        if p in ("between", "cost", "shapes"):
            globals()[p](res[p], work)
        else:
            globals()[p](res[p])
    (work / f"inflight-{'-'.join(parts)}.json").write_text(json.dumps(res, indent=1, default=str))


if __name__ == "__main__":
    main()
