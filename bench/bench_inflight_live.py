"""`forcemap run --replan` flown live against the simulator on its ptys, as a user would (issue 31).

    python bench/bench_inflight_live.py --work /tmp/inflight-live [--speed 3 --speed 10]
        [--mission plain.waypoints --mission plain.plan] [--reference]

For each mission file (bench/mission_shapes.py writes them: the simulator's river lawnmower as a WPL
file and as a QGC .plan with a survey complex item) and each --speed: `forcemap sim --scenario river
--mission FILE --speed S --ports P -o TRUTH --seed 5` and `forcemap run --mavlink ... --clock sim:...
--mission FILE --replan`, two processes as in the field. The true track (TRUTH/samples.csv) is scored
against the original survey lines 3 to 5, up to the boat's arrival at the mission's last waypoint
(after it the motor is off and the boat drifts with the river). Prints a markdown row per run with the decisions from the
log (made, uploaded, late, refused), the wall time, the load average and how often the simulator fell
behind its speed (a loaded machine), and writes WORK/live.json.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from forcemap.host.log.mcap import read_messages
from forcemap.host.plan.metrics import score_lines, summary
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.vessel.mission import read_items

from bench.mission_shapes import shape, write

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "forcemap.host.cli"]
DURATION = "14m"  # the mission once through is 11-12 min; the rest is cut (mission_end)


def fly_live(mission: Path, speed: float, work: Path, replan: bool = True, seed: int = 5) -> dict:
    """One live flight; the scores on survey lines 3-5 and the log's decisions."""
    tag = f"{mission.name}-x{speed:g}{'' if replan else '-ref'}"
    ports, truth, out = work / tag / "ports", work / tag / "truth", work / tag / "log"
    for d in (truth, out):
        d.mkdir(parents=True, exist_ok=True)
    run = [*CLI, "run", "-o", str(out), "--quiet", "--mavlink", str(ports / "mavlink"),
           "--bridge", str(ports / "bridge"), "--clock", f"sim:{ports / 'clock'}",
           "--clock-wait", "120s", *(["--mission", str(mission), "--replan"] if replan else [])]  # fmt: skip
    sim = [*CLI, "sim", "--scenario", "river", "--mission", str(mission), "--speed", f"{speed:g}",
           "--duration", DURATION, "--ports", str(ports), "-o", str(truth), "--seed", str(seed),
           "--force"]  # fmt: skip
    load0 = os.getloadavg()[0]
    t0 = time.monotonic()
    daemon = subprocess.Popen(
        run, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    s = subprocess.run(sim, cwd=ROOT, capture_output=True, text=True, timeout=3600)
    wall = time.monotonic() - t0
    load1 = os.getloadavg()[0]
    time.sleep(3.0)  # the daemon writes what it has read
    daemon.send_signal(signal.SIGINT)
    try:
        _, err = daemon.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        daemon.kill()
        _, err = daemon.communicate()
    if s.returncode != 0:
        raise RuntimeError(f"sim failed: {s.stderr[-2000:]}")
    behind = next(
        (ln for ln in s.stdout.splitlines() + s.stderr.splitlines() if "fell behind" in ln), ""
    )
    rows = np.genfromtxt(truth / "samples.csv", delimiter=",", names=True)
    recs = [
        m.message for p in sorted(out.rglob("*.mcap")) for m in read_messages(p, "/plan/replan")
    ]
    rows = rows[: mission_end(rows, recs, mission)]
    xy = np.column_stack([rows["x"], rows["y"]])
    survey = shape("plain")[1]
    scores = score_lines(rows["t"], xy, survey)
    judged = summary(scores[2:])
    res = {
        "case": tag, "p95_worst_judged": round(float(judged["p95_worst_line"]), 2),
        "coverage_judged": round(float(judged["coverage"]), 4),
        "per_line": [f"{x.p95:.2f}/{x.coverage:.0%}" for x in scores],
        "decisions": len(recs), "uploaded": sum(bool(r["uploaded"]) for r in recs),
        "late": sum(bool(r.get("late")) for r in recs),
        "refused": sum(bool(r.get("refused")) for r in recs),
        "reasons": [r["reason"] for r in recs], "cpu_s": [r.get("cpu_s") for r in recs],
        "map_cpu_s": [r.get("map_cpu_s") for r in recs], "wall_s": round(wall),
        "load": [round(load0, 1), round(load1, 1)], "behind": behind,
        "daemon_tail": err[-600:] if not recs else "",
    }  # fmt: skip
    print(
        f"| {tag} | {res['p95_worst_judged']:.2f} | {res['coverage_judged']:.1%} | "
        f"{' · '.join(res['per_line'])} | {res['decisions']}/{res['uploaded']}/{res['late']}/"
        f"{res['refused']} | {res['wall_s']} | {load0:.1f}-{load1:.1f} | {behind or 'kept pace'} |",
        flush=True,
    )
    return res


def mission_end(rows: np.ndarray, recs: list[dict], mission: Path) -> int:
    """The truth's row where the boat reached the last waypoint of the mission it held at the end:
    after it the motor is off and the boat drifts with the river, which is no survey line's pass."""
    uploaded = [r for r in recs if r["uploaded"]]
    if uploaded:
        lat, lon = uploaded[-1]["new_remaining"][-1][:2]
    else:
        last = read_items(mission)[1][-1]
        lat, lon = last.lat, last.lon
    frame = LocalFrame(float(lat), float(lon))
    d = np.hypot(*frame.to_local(rows["lat"], rows["lon"]))
    after = rows["t"] >= (uploaded[-1]["t"] if uploaded else rows["t"][0])
    hit = np.flatnonzero(after & (d < 6.0))
    return int(hit[0]) + 1 if len(hit) else len(rows)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--work", default="/tmp/inflight-live", type=Path)
    ap.add_argument("--speed", type=float, action="append")
    ap.add_argument("--mission", action="append", help="plain.waypoints, plain.plan, ...")
    ap.add_argument("--reference", action="store_true", help="also fly without --replan")
    a = ap.parse_args()
    a.work.mkdir(parents=True, exist_ok=True)
    files = write("plain", a.work / "missions")
    by_name = {f.name: f for f in files}
    print("| run | p95 worst line m (3-5) | coverage (3-5) | per line p95/coverage | decisions/"
          "uploaded/late/refused | wall s | load | simulator |\n|---|---:|---:|---|---|---:|---|---|")  # fmt: skip
    out = []
    for name in a.mission or ["plain.waypoints", "plain.plan"]:
        for speed in a.speed or [3.0, 10.0]:
            if a.reference:
                out.append(fly_live(by_name[name], speed, a.work, replan=False))
            out.append(fly_live(by_name[name], speed, a.work))
    (a.work / "live.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
