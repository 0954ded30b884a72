"""Benchmark: the live simulator and the daemon on a busy machine, against the same run on an idle one.

`forcemap sim` (river, default faults, seed 1) and `forcemap run` on its ptys, at x80, the way
`forcemap demo` runs them (the daemon first). The baseline is an idle machine; the other runs start
N processes that spin a core each (2 of them load both cores of the machine, as the other test
worker and a fitting job did when CI failed). For each it prints what a user would see in the log:
samples without a boat state, the autopilot clock's epochs (a healthy run has one per autopilot
boot), the log's time span against the simulated duration, and the simulator's re-anchors.

    python bench/bench_busy_machine.py [--hogs 0,1,2] [--duration 360] [--speed 80]
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from forcemap.host.log.mcap import read_messages

SPIN = "while True: pass"


def forcemap(*args: str) -> list[str]:
    return [sys.executable, "-m", "forcemap.host.cli", *args]


def survey(d: Path, duration: float, speed: float, hogs: int) -> dict[str, float]:
    ports, logs = d / "ports", d / "logs"
    spinners = [subprocess.Popen([sys.executable, "-c", SPIN]) for _ in range(hogs)]
    try:
        daemon = subprocess.Popen(
            forcemap(
                "run", "--bridge", str(ports / "bridge"), "--depth", str(ports / "depth"),
                "--mavlink", f"{ports / 'mavlink'},115200", "--clock", f"sim:{ports / 'clock'}",
                "-o", str(logs), "--quiet",
            ),
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        t0 = time.perf_counter()
        sim = subprocess.run(
            forcemap(
                "sim", "--scenario", "river", "--duration", f"{duration:g}s", "--speed", f"{speed:g}",
                "--faults", "default", "--seed", "1", "--ports", str(ports),
            ),
            capture_output=True, text=True, check=True,
        )  # fmt: skip
        wall = time.perf_counter() - t0
        time.sleep(0.5)
        daemon.send_signal(signal.SIGINT)
        daemon.wait(30)
    finally:
        for p in spinners:
            p.kill()
            p.wait()
    reanchors = 0
    for line in sim.stdout.splitlines():
        if line.startswith("the machine fell behind"):
            reanchors = int(line.split()[5])
    [path] = sorted(logs.glob("*.mcap"))
    rows = [m.message for m in read_messages(path, "/samples")]
    epochs = {
        m.message["epoch"]
        for m in read_messages(path, "/timesync")
        if m.message.get("source") == "mavlink" and m.message.get("kind") == "device"
    }
    t = [r["t"] for r in rows]
    return {
        "samples": len(rows),
        "without_state": sum(r["lat"] is None for r in rows),
        "epochs": len(epochs),
        "span": max(t) - min(t),
        "reanchors": reanchors,
        "wall": wall,
    }


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--hogs", default="0,1,2", help="spinning processes per run (0 = the baseline)")
    ap.add_argument("--duration", type=float, default=360.0, help="simulated seconds")
    ap.add_argument("--speed", type=float, default=80.0)
    args = ap.parse_args()
    hogs = [int(h) for h in args.hogs.split(",")]
    if 0 not in hogs:
        hogs.insert(0, 0)
    print(f"river, default faults, {args.duration:g} s at x{args.speed:g}; baseline: idle machine")
    print(
        f"{'spinners':>8} {'samples':>8} {'no state':>9} {'vs idle':>8} {'mav epochs':>10} "
        f"{'span/sim':>8} {'re-anchors':>10} {'wall':>6}"
    )
    base = None
    for h in hogs:
        with tempfile.TemporaryDirectory() as d:
            r = survey(Path(d), args.duration, args.speed, h)
        base = base or r
        ratio = r["without_state"] / max(base["without_state"], 1)
        print(
            f"{h:>8} {r['samples']:>8} {r['without_state']:>9} {ratio:>7.1f}x {r['epochs']:>10} "
            f"{r['span'] / args.duration:>8.2f} {r['reanchors']:>10} {r['wall']:>5.1f}s",
            flush=True,
        )


if __name__ == "__main__":
    main()
