"""Long simulated surveys for the time terms (a tide over a day, a seiche over hours), made cheaply.

A day through the whole offline pipeline at 4 Hz is 345,600 rows and about 12 minutes of CPU (10 s per
simulated 20 minutes on this machine). The time terms need the day, not the rows: `truth_survey` flies the
mission in the simulator with its instruments off (the physics alone, stepped at PHYSICS_DT_S: 0.6 s of
CPU per simulated hour) and writes the true track as a samples table every `every_s` seconds, with the measurement error the pipeline
leaves on the simulator's 20-minute survey (measured against its truth, seed 1, the `tidal_stream`
river: 0.037 m/s per current component and 0.08 m for depth, uncorrelated beyond 5 s) added as independent
Gaussian noise. The truth files (effects.json, the true samples) are written beside it as the full
simulator writes them.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
from forcemap.sim_devices import truth as truth_files
from forcemap.sim_devices.engine import Simulation

# the boat's step without instruments: 5 Hz flies the same track as the instruments' 20 Hz (3 h of the
# tidal river, seed 1: the same 139 legs, cross-track p50 0.99 m both, p95 3.84 against 3.82 m) at a
# quarter of the CPU
PHYSICS_DT_S = 0.2
CURRENT_NOISE_M_S = 0.037
DEPTH_NOISE_M = 0.08
COLUMNS = (
    "t", "lat", "lon", "heading", "yaw_rate", "sog", "cog", "depth", "current_east", "current_north",
    "current_speed", "current_dir", "wind_east", "wind_north", "wind_speed", "wind_dir", "water_temp",
)  # fmt: skip


def truth_survey(
    scenario: str,
    effects: list[str],
    seed: int,
    duration_s: float,
    out_dir: str | Path,
    every_s: float = 5.0,
    mission: str | None = None,
) -> Path:
    """A samples table (`out_dir/samples.csv`) of a `duration_s` survey from the true track, one row per
    `every_s`, with the pipeline's measurement noise; reused if already there."""
    out = Path(out_dir)
    table = out / "samples.csv"
    if table.exists():
        return table
    out.mkdir(parents=True, exist_ok=True)
    sim = Simulation(scenario, mission, effects, seed=seed, instruments=False, dt=PHYSICS_DT_S)
    sim.run(duration_s, lambda *a: None)
    rows = sim.truth_table()
    cols = {c: rows[:, i] for i, c in enumerate(truth_files.COLUMNS)}
    keep = np.unique(np.floor((cols["t"] - cols["t"][0]) / every_s), return_index=True)[1]
    cols = {c: v[keep] for c, v in cols.items()}
    truth = out / "truth"
    truth.mkdir(exist_ok=True)
    (truth / "effects.json").write_text(json.dumps(sim.meta(), indent=2, default=float) + "\n")
    np.savez_compressed(truth / "samples.npz", **cols)
    rng = np.random.default_rng([seed, 37])
    n = len(keep)
    cols["current_east"] = cols["current_east"] + rng.normal(0, CURRENT_NOISE_M_S, n)
    cols["current_north"] = cols["current_north"] + rng.normal(0, CURRENT_NOISE_M_S, n)
    cols["current_speed"] = np.hypot(cols["current_east"], cols["current_north"])
    cols["current_dir"] = truth_files.compass(cols["current_east"], cols["current_north"])
    cols["depth"] = cols["depth"] + rng.normal(0, DEPTH_NOISE_M, n)  # the truth's holds the level
    with table.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for i in range(n):
            w.writerow([f"{cols[c][i]:.8f}" if c in ("lat", "lon") else f"{cols[c][i]:.4f}"
                        for c in COLUMNS])  # fmt: skip
    return table
