"""What `forcemap run`'s navigation filter costs (issue 29): `python bench/bench_live_filter.py`.

The simulator's river survey with every navigation source of the issue (two receivers sending RMC,
GGA and GLL at their own stamps, one fixing every 4 s; a gyro compass 5 s late, a fluxgate at 5 Hz,
a rate-of-turn sensor), generated once, then fed in this process through the daemon's pipeline
twice: without the filter (the baseline: the chosen source's last fix) and with it
(``live_filter=True``, as `forcemap run` makes it). CPU is ``time.process_time`` of each feed,
never wall time; at 1x real time, a pipeline's CPU per simulated second is its share of one core.

    python bench/bench_live_filter.py [--minutes 10] [--bridge]
    python bench/bench_live_filter.py --daemon 5m [--speed 1]   # two real daemons, real time

``--bridge`` adds the bridge (its 4-Hz SAMPLEs pace the rows; the autopilot is left out, so the
navigation is the NMEA sources').
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

FAULTS = "nav_receivers,late_compass,rate_of_turn"


def feed(chunks: list[tuple[str, int, bytes]], live: bool) -> tuple[float, dict]:
    """CPU seconds of the pipeline over ``chunks``, and its counters."""
    from forcemap.host.fuse import calibration
    from forcemap.host.fuse.pipeline import NullSink, Pipeline

    sink = NullSink()
    pipe = Pipeline(calibration.load(None), sink, live_filter=live)
    rng = random.Random(1)
    c0 = time.process_time()
    for source, t, data in chunks:
        a = t + int(rng.uniform(0.2e6, 3e6))
        pipe.feed(source, a, a, data)
    pipe.close()
    cpu = time.process_time() - c0
    got = {"rows": sink.counts["/samples"], "errors": dict(pipe.errors)}
    if pipe.live_nav is not None:
        got["filter"] = dict(pipe.live_nav.counts)
    return cpu, got


def daemons(duration: str, speed: float) -> dict:
    """Two `forcemap run` daemons at ``speed``, each on its own simulator (same seed and faults,
    NMEA bus and sounder): one with the filter, one with ``[sync] navigation = "logged"`` (the
    baseline). CPU: each process's user+system seconds (psutil), never wall time."""
    import subprocess

    from bench.bench_live import _cpu

    tmp = Path(tempfile.mkdtemp(prefix="bench_live_filter_"))
    procs, sims = {}, {}
    for name, boat in (("filter", ""), ("plain", '[sync]\nnavigation = "logged"\n')):
        base = tmp / name
        (base / "out").mkdir(parents=True)
        (base / "boat.toml").write_text(boat)
        ports = base / "ports"
        procs[name] = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "forcemap.host.cli",
                "run",
                "--quiet",
                "-o",
                str(base / "out"),
                "--nmea",
                str(ports / "nmea"),
                "--depth",
                str(ports / "depth"),
                "--boat",
                str(base / "boat.toml"),
                "--clock",
                f"sim:{ports / 'clock'}",
                "--clock-wait",
                "60s",
            ],  # fmt: skip
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        sims[name] = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "forcemap.host.cli",
                "sim",
                "--scenario",
                "river",
                "--faults",
                FAULTS,
                "--speed",
                str(speed),
                "--duration",
                duration,
                "--ports",
                str(ports),
                "-o",
                str(base / "truth"),
                "--seed",
                "1",
            ],  # fmt: skip
            cwd=ROOT,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    t0 = time.monotonic()
    peak = {n: 0.0 for n in procs}
    while any(s.poll() is None for s in sims.values()):
        for n, p in procs.items():
            peak[n] = max(peak[n], _cpu(p))
        time.sleep(2.0)
    wall = time.monotonic() - t0
    for n, p in procs.items():
        peak[n] = max(peak[n], _cpu(p))
        p.send_signal(15)
    for p in procs.values():
        p.wait(120)
    return {"wall_s": wall, **{f"cpu_{n}_s": v for n, v in peak.items()}, "dir": str(tmp)}


def main() -> None:
    from forcemap.sim_devices.engine import Simulation

    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--bridge", action="store_true")
    ap.add_argument("--daemon", metavar="DURATION", help="two real daemons at 1x, e.g. 5m")
    ap.add_argument("--speed", type=float, default=1.0)
    args = ap.parse_args()
    if args.daemon:
        got = daemons(args.daemon, args.speed)
        survey = got["wall_s"] * args.speed
        for n in ("plain", "filter"):
            cpu = got[f"cpu_{n}_s"]
            print(f"daemon {n:6s}: {cpu:6.2f} s CPU over {got['wall_s']:.0f} s: "
                  f"{100 * cpu / got['wall_s']:.2f} % of a core")  # fmt: skip
        print(f"({survey:.0f} s simulated; logs in {got['dir']})")
        return
    ports = {"nmea", "depth"} | ({"bridge"} if args.bridge else set())
    duration = args.minutes * 60
    with tempfile.TemporaryDirectory() as tmp:
        sim = Simulation(
            scenario="river", faults=FAULTS, seed=1, truth_dir=Path(tmp), nmea_bus=True
        )
        chunks: list[tuple[str, int, bytes]] = []
        sim.run(duration, lambda s, t, d: chunks.append((s, t, d)) if s in ports else None)
    plain, p_info = feed(chunks, live=False)
    live, l_info = feed(chunks, live=True)
    print(f"{args.minutes:g} min simulated, ports {sorted(ports)}, {len(chunks)} chunks")
    print(
        f"plain pipeline : {plain:6.2f} s CPU  {100 * plain / duration:5.2f} % of a core  {p_info}"
    )
    print(f"with the filter: {live:6.2f} s CPU  {100 * live / duration:5.2f} % of a core  {l_info}")
    solves = l_info.get("filter", {}).get("solves", 0)
    extra = live - plain
    print(
        f"the filter's own: {extra:.2f} s CPU = {100 * extra / duration:.2f} % of a core, "
        f"{1000 * extra / max(solves, 1):.1f} ms per solve ({solves} solves), "
        f"ratio {live / plain:.1f}x the plain pipeline"
    )


if __name__ == "__main__":
    main()
