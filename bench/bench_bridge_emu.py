"""Emulated-bridge speed as a multiple of real time, under the river simulation's edge load.

The load: a 10 Hz anemometer with two bounce edges per closure and four paddle wheels at
60-70 Hz (about 300 edges per simulated second), fed in 100 ms simulation steps as the simulator
does, frames written to a byte sink. Baseline in the same process: a bare loop that only advances
a VirtualClock by the same steps.

    python bench/bench_bridge_emu.py [--seconds 600]
"""

from __future__ import annotations

import argparse
import random
import time

from forcemap.sim_devices.bridge_emu import EmulatedBridge, add_bounce, pulse_times
from forcemap.sim_devices.machine_emu import VirtualClock

STEP_US = 100_000
RATES_HZ = (10.0, 61.0, 64.0, 67.0, 70.0)


def baseline(seconds: int) -> float:
    clock = VirtualClock()
    t0 = time.perf_counter()
    for _ in range(seconds * 1_000_000 // STEP_US):
        clock.sleep_us(STEP_US)
    return time.perf_counter() - t0


def emulated(seconds: int) -> tuple[float, int, int]:
    sink = bytearray()
    emu = EmulatedBridge(lambda b: sink.extend(b) or len(b), seed=1)
    rng = random.Random(1)
    phase = [0.0] * 5
    t0 = time.perf_counter()
    for k in range(seconds * 1_000_000 // STEP_US):
        a, b = k * STEP_US, (k + 1) * STEP_US
        for ch, hz in enumerate(RATES_HZ):
            times, phase[ch] = pulse_times(hz, a, b, phase[ch])
            emu.add_edges(ch, add_bounce(times, 300, 2, rng) if ch == 0 else times)
        emu.advance_to(b)
    return time.perf_counter() - t0, emu.edges_fired, len(sink)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=int, default=600, help="simulated seconds")
    n = ap.parse_args().seconds
    base = baseline(n)
    wall, edges, nbytes = emulated(n)
    print(f"simulated {n} s: {edges} edges ({edges / n:.0f}/s), {nbytes} bytes of frames")
    print(f"baseline (bare clock loop): {n / base:,.0f}x real time ({base * 1e3:.1f} ms)")
    print(f"emulated bridge:            {n / wall:,.0f}x real time ({wall * 1e3:.1f} ms)")
    print(f"per edge: {wall / edges * 1e6:.2f} us wall, including pulse generation and frames")


if __name__ == "__main__":
    main()
