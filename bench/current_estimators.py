"""The paper's F1/F2 current estimate against least squares, by flow angle and boat speed.

    python bench/current_estimators.py               # both tables, markdown, for docs/COMPENSATION.md
    python bench/current_estimators.py --sim-duration 0   # the synthetic table only

1. Synthetic: the four wheels at 45/135/-135/-45 deg read |F . axis| for a water velocity F relative
   to the hull, plus Gaussian noise (0.02 m/s + 2 %) and the 0.05 m/s cut-off, 2000 draws per cell;
   the current is 0.5 m/s in a random direction. Error = |estimated current - true current|.
2. Simulator: the river survey from ``forcemap.sim_devices.engine`` through the whole pipeline (bytes, clocks,
   pulse rates, interpolated boat state), compared with the simulator's truth at each sample.

Cells show the median and the 95th percentile of the error in m/s.
"""

from __future__ import annotations

import argparse
import csv
import math
import random
import sys
import tempfile
from pathlib import Path

import numpy as np
from forcemap.host.fuse import compensation as comp
from forcemap.host.vessel.geodesy import boat_to_world, velocity, world_to_boat

WHEELS = (45.0, 135.0, -135.0, -45.0)
ANGLES = (0, 15, 30, 45, 60, 90, 135, 180)
SPEEDS = (0.5, 1.0, 2.0, 3.0)


def synthetic(n: int = 2000, seed: int = 1) -> dict[tuple[int, float], dict[str, list[float]]]:
    rng = random.Random(seed)
    out: dict[tuple[int, float], dict[str, list[float]]] = {}
    for ang in ANGLES:
        for sp in SPEEDS:
            errs: dict[str, list[float]] = {"lsq": [], "paper": []}
            for _ in range(n):
                rel = ang * rng.choice((-1, 1))  # the water comes from rel deg off the bow
                heading = rng.uniform(0, 360)
                c = velocity(0.5, rng.uniform(0, 360))
                f = -sp * math.cos(math.radians(rel))
                s = -sp * math.sin(math.radians(rel))
                # boat velocity over ground: the water's, minus the flow past the hull
                fe, fn = boat_to_world(f, s, heading)
                v = (c[0] - fe, c[1] - fn)
                m = []
                for r in comp.wheel_readings(f, s, WHEELS):
                    r = max(0.0, r * (1 + rng.gauss(0, 0.02)) + rng.gauss(0, 0.02))
                    m.append(r if r >= 0.05 else 0.0)
                (lf, ls), _ = comp.current_lsq(m, WHEELS, 0.03)
                pf, ps = comp.current_paper(m, WHEELS)
                for name, (a, b) in (("lsq", (lf, ls)), ("paper", (pf, ps))):
                    ce, cn = comp.current_over_ground(a, b, heading, *v)
                    errs[name].append(math.hypot(ce - c[0], cn - c[1]))
            out[(ang, sp)] = errs
    return out


def from_sim(duration: float, seed: int = 1):
    """(flow angle deg, speed through water, lsq error, paper error) per sample of a simulated survey."""
    from forcemap.host.fuse.calibration import Calibration
    from forcemap.host.fuse.pipeline import ListSink, Pipeline
    from forcemap.sim_devices.engine import Simulation

    with tempfile.TemporaryDirectory() as tmp:
        sink = ListSink()
        pipe = Pipeline(Calibration(), sink)
        Simulation(seed=seed, truth_dir=tmp).run(
            duration, lambda src, t, data: pipe.feed(src, t + 2_000_000, t + 2_000_000, bytes(data))
        )
        pipe.close()
        rows = list(csv.DictReader(open(Path(tmp) / "samples.csv")))
    cols = {
        k: np.array([float(r[k]) for r in rows])
        for k in ("t", "heading", "boat_east", "boat_north", "current_east", "current_north")
    }
    hs = np.unwrap(np.radians(cols["heading"]))
    out = []
    for r in sink.topic("/samples"):
        if r["current_east"] is None or r["current_speed_paper"] is None:
            continue
        t = r["t"]
        tru = {k: float(np.interp(t, cols["t"], v)) for k, v in cols.items() if k != "heading"}
        h = math.degrees(float(np.interp(t, cols["t"], hs)))
        f, s = world_to_boat(
            tru["current_east"] - tru["boat_east"], tru["current_north"] - tru["boat_north"], h
        )
        ang = abs(math.degrees(math.atan2(-s, -f)))
        pe, pn = velocity(r["current_speed_paper"], r["current_dir_paper"])
        e_l = math.hypot(
            r["current_east"] - tru["current_east"], r["current_north"] - tru["current_north"]
        )
        e_p = math.hypot(pe - tru["current_east"], pn - tru["current_north"])
        out.append((ang, math.hypot(f, s), e_l, e_p))
    return out


def cell(v: list[float]) -> str:
    if not v:
        return "-"
    a = np.asarray(v)
    return f"{np.median(a):.2f} / {np.percentile(a, 95):.2f}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2000)
    ap.add_argument("--sim-duration", type=float, default=1800.0)
    args = ap.parse_args(argv)

    res = synthetic(args.n)
    print(
        "### Synthetic |cos| wheels, 0.5 m/s current (median / p95 error, m/s): least squares | paper\n"
    )
    print("| flow from (deg off bow) | " + " | ".join(f"{s} m/s" for s in SPEEDS) + " |")
    print("|---|" + "---|" * len(SPEEDS))
    for ang in ANGLES:
        cells = [f"{cell(res[(ang, s)]['lsq'])} \\| {cell(res[(ang, s)]['paper'])}" for s in SPEEDS]
        print(f"| {ang} | " + " | ".join(cells) + " |")
    tot = {k: [e for v in res.values() for e in v[k]] for k in ("lsq", "paper")}
    print(f"\nall cells: least squares {cell(tot['lsq'])}, paper {cell(tot['paper'])}\n")

    if args.sim_duration > 0:
        try:
            rows = from_sim(args.sim_duration)
        except ImportError as e:
            print(f"(simulator not available: {e})")
            return 0
        abins = ((0, 15), (15, 30), (30, 45), (45, 90), (90, 181))
        sbins = ((0.0, 0.5), (0.5, 1.5), (1.5, 3.0), (3.0, 99.0))
        print(
            f"### Simulator river survey, {args.sim_duration:.0f} s, {len(rows)} samples "
            "(median / p95 error, m/s): least squares | paper\n"
        )
        print(
            "| flow from (deg off bow) | "
            + " | ".join(f"{a}-{b} m/s" if b < 99 else f">{a} m/s" for a, b in sbins)
            + " | n |"
        )
        print("|---|" + "---|" * (len(sbins) + 1))
        for a0, a1 in abins:
            cells = []
            n = 0
            for s0, s1 in sbins:
                sel = [r for r in rows if a0 <= r[0] < a1 and s0 <= r[1] < s1]
                n += len(sel)
                cells.append(
                    f"{cell([r[2] for r in sel])} \\| {cell([r[3] for r in sel])}" if sel else "-"
                )
            print(f"| {a0}-{min(a1, 180)} | " + " | ".join(cells) + f" | {n} |")
        print(
            f"\nall samples: least squares {cell([r[2] for r in rows])}, paper {cell([r[3] for r in rows])}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
