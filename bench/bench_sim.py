"""Simulator speed-up over real time on this machine: the river survey with every instrument running.

    python bench/bench_sim.py [--minutes 30] [--live]

Baseline, in the same process: the world and the boat alone (no instruments, no bytes). The full run
adds the bridge firmware on emulated pins, the sounder, the autopilot and truth logging. ``--live``
also drives the ptys flat out with a reader draining them (the ``forcemap sim`` transport).
"""

from __future__ import annotations

import argparse
import tempfile
import threading
import time

from forcemap.sim_devices.engine import Simulation


def timed(sim: Simulation, duration_s: float) -> tuple[float, int]:
    n = [0]

    def sink(source: str, t_ns: int, data: bytes) -> None:
        n[0] += len(data)

    t = time.perf_counter()
    sim.run(duration_s, sink)
    return time.perf_counter() - t, n[0]


def live(duration_s: float) -> float:
    import serial
    from forcemap.sim_devices.ports import SOURCES, PortSet, run_live

    with tempfile.TemporaryDirectory() as d:
        ports = PortSet(d)
        opened = [serial.Serial(ports.path(s), timeout=0) for s in SOURCES]
        done = threading.Event()

        def drain() -> None:
            while not done.is_set():
                for p in opened:
                    if p.in_waiting:
                        p.read(p.in_waiting)
                time.sleep(0.005)

        th = threading.Thread(target=drain, daemon=True)
        th.start()
        t = time.perf_counter()
        run_live(
            lambda **kw: Simulation("river", "lawnmower", effects=["depth_current"], **kw),
            ports,
            duration_s,
            speed=1e6,
        )
        wall = time.perf_counter() - t
        done.set()
        th.join()
        for p in opened:
            p.close()
        ports.close()
    return duration_s / wall


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--live", action="store_true", help="also measure the pty transport flat out")
    args = ap.parse_args()
    dur = args.minutes * 60.0
    base_wall, _ = timed(
        Simulation("river", "lawnmower", effects=["depth_current"], instruments=False), dur
    )
    full_wall, nbytes = timed(Simulation("river", "lawnmower", effects=["depth_current"]), dur)
    fault_wall, _ = timed(
        Simulation("river", "lawnmower", effects=["depth_current"], faults="default"), dur
    )
    print(f"river, {args.minutes:g} simulated minutes, boat at 20 Hz, truth at 10 Hz")
    print(
        f"  baseline (world + boat, no instruments)   {base_wall:6.2f} s wall  {dur / base_wall:7.0f}x real time"
    )
    print(
        f"  all instruments ({nbytes / 1e6:.1f} MB of bytes)          {full_wall:6.2f} s wall  {dur / full_wall:7.0f}x real time"
    )
    print(
        f"  all instruments + default faults          {fault_wall:6.2f} s wall  {dur / fault_wall:7.0f}x real time"
    )
    print(
        f"  instruments cost {full_wall / base_wall:.1f}x the baseline; offline speed-up {dur / full_wall:.0f}x"
    )
    if args.live:
        print(f"  live ptys flat out (10 min):  {live(600.0):7.0f}x real time")


if __name__ == "__main__":
    main()
