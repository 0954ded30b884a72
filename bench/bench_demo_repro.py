"""`forcemap demo --seed 1` twice, once as the machine is and once with two processes spinning both
cores on top: the CV RMSEs it prints must agree to 3 significant digits (issue 33, item 7).

    python bench/bench_demo_repro.py [--duration 35m] [--seed 1] [--hogs 0,2]

Prints, per run, its wall time, the load average at its start, the lockstep line of the simulator,
every blocked-CV RMSE the demo printed, and whether the runs agree.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SPIN = "while True: pass"
RMSE = re.compile(r"RMSE[^0-9\n]*([0-9]+\.[0-9]+)")


def demo(out: Path, duration: str, seed: int, hogs: int) -> dict:
    spinners = [subprocess.Popen([sys.executable, "-c", SPIN]) for _ in range(hogs)]
    load = os.getloadavg()[0]
    t = time.monotonic()
    try:
        res = subprocess.run(
            [sys.executable, "-m", "forcemap.host.cli", "demo", "-o", str(out),
             "--duration", duration, "--seed", str(seed)],
            capture_output=True, text=True, timeout=7200,
        )  # fmt: skip
    finally:
        for p in spinners:
            p.kill()
            p.wait()
    if res.returncode != 0:
        raise SystemExit(f"demo failed:\n{res.stdout[-2000:]}\n{res.stderr[-2000:]}")
    fits = [json.loads((out / n).read_text())["cv_rmse"] for n in ("fit-baseline.json",)]
    refit = out / "fit-refit.json"
    if refit.exists():
        fits.append(json.loads(refit.read_text())["cv_rmse"])
    return {
        "hogs": hogs,
        "load": load,
        "wall_s": time.monotonic() - t,
        "lockstep": [ln for ln in res.stdout.splitlines() if ln.startswith("lockstep")],
        "printed": RMSE.findall(res.stdout),
        "fits": fits,
    }


def sig3(values) -> list[str]:
    return [f"{float(v):.3g}" for v in values]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", default="35m")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--hogs", default="0,2")
    args = ap.parse_args()
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for hogs in map(int, args.hogs.split(",")):
            r = demo(Path(tmp) / f"demo{hogs}", args.duration, args.seed, hogs)
            runs.append(r)
            print(
                f"spinners {hogs}: load {r['load']:.1f} at start, {r['wall_s']:.0f} s wall; "
                f"{' '.join(r['lockstep'])}\n  printed RMSEs {r['printed']}\n  fits' cv_rmse {r['fits']}",
                flush=True,
            )
    same = all(sig3(r["printed"]) == sig3(runs[0]["printed"]) for r in runs)
    same_fits = all(r["fits"] == runs[0]["fits"] for r in runs)
    print(f"printed RMSEs agree to 3 significant digits: {same}; fits identical: {same_fits}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
