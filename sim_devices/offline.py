"""Offline surveys: the simulator's bytes go straight into the daemon's pipeline, as fast as possible.

The instruments, the firmware, the pipeline, the MCAP log and the export are the real ones; only the
serial transport and the host's clock are left out (arrival time = virtual send time + a small,
seeded USB/serial latency). Tests and `forcemap demo` use it to make surveys with known hidden effects.

    csv = make_survey("river", ["depth_current"], seed=1, duration_s=1200, out_dir="out/s1")
"""

from __future__ import annotations

import random
from collections.abc import Callable
from pathlib import Path

from forcemap.host.convert.export import export
from forcemap.host.fuse import calibration
from forcemap.host.fuse.pipeline import Pipeline
from forcemap.host.log.mcap import McapLog

from .engine import Simulation


def run_to_mcap(
    sim: Simulation,
    duration_s: float,
    log_dir: Path,
    *,
    seed: int = 0,
    progress: Callable[[float, float], object] | None = None,
    ports: tuple[str, ...] | None = None,
    boat: calibration.Calibration | None = None,
) -> list[Path]:
    """Run ``sim`` for ``duration_s`` through the real pipeline into MCAP files in ``log_dir``.

    ``ports``: only these of the simulator's ports reach the pipeline (an NMEA-only boat:
    ``("nmea", "depth")``); ``boat``: the boat file (default: the defaults).
    """
    rng = random.Random(seed)
    log = McapLog(log_dir)
    pipe = Pipeline(boat if boat is not None else calibration.load(None), log)

    def sink(source: str, t_ns: int, data: bytes) -> None:
        if ports is not None and source not in ports:
            return
        # USB-CDC and UART reads reach the host 0.2-3 ms after the device sends them
        arrival = t_ns + int(rng.uniform(0.2e6, 3e6))
        pipe.feed(source, arrival, arrival, data)

    try:
        sim.run(duration_s, sink, progress=progress)
    finally:
        pipe.close()
        log.close()
    return list(log.paths)


def make_survey(
    scenario: str,
    effects: list[str],
    seed: int,
    duration_s: float,
    out_dir: str | Path,
    *,
    mission: str | None = None,
    faults: str | None = None,
    fmt: str = "csv",
    progress: Callable[[float, float], object] | None = None,
) -> Path:
    """Simulate a survey, log it through the daemon's pipeline and export its samples table.

    Returns the table's path; ``out_dir/truth/`` holds the simulator's ground truth and
    ``out_dir/logs/`` the MCAP files.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sim = Simulation(
        scenario=scenario,
        mission=mission,
        effects=effects,
        faults=faults,
        seed=seed,
        truth_dir=out / "truth",
    )
    paths = run_to_mcap(sim, duration_s, out / "logs", seed=seed, progress=progress)
    table = out / f"samples.{fmt}"
    export(paths, fmt, str(table))
    return table
