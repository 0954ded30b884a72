"""An NMEA-only boat from the simulator (its NMEA bus and sounder, no bridge, no autopilot) through
the real pipeline, and the figures issue 20 asks for, measured against the simulator's truth."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from forcemap.host.fuse import calibration
from forcemap.host.log.mcap import read_messages
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.offline import run_to_mcap

EARTH_R = 6_371_000.0
NMEA_ONLY = ("nmea", "depth")


def run(
    out: Path,
    faults: str | None,
    *,
    seed: int = 1,
    duration_s: float = 600.0,
    scenario: str = "river",
    boat_toml: str = "",
) -> tuple[list[Path], np.ndarray, Simulation]:
    """The MCAP files, the truth table (structured array) and the simulation."""
    sim = Simulation(
        scenario=scenario, faults=faults, seed=seed, truth_dir=out / "truth", nmea_bus=True
    )
    boat = calibration.loads(boat_toml) if boat_toml else None
    paths = run_to_mcap(sim, duration_s, out / "logs", seed=seed, ports=NMEA_ONLY, boat=boat)
    truth = np.genfromtxt(out / "truth" / "samples.csv", delimiter=",", names=True)
    return paths, truth, sim


def samples(paths: list[Path]) -> dict[str, np.ndarray]:
    """The /samples rows as columns (None -> NaN)."""
    rows = [m.message for m in read_messages(paths, "/samples")]
    keys = ("t", "lat", "lon", "sog", "yaw_rate", "heading", "current_east", "current_north")
    return {k: np.array([np.nan if r.get(k) is None else r[k] for r in rows]) for k in keys}


def figures(paths: list[Path], truth: np.ndarray) -> dict[str, Any]:
    """Speed from successive positions against SOG (p95), yaw rate p99 against the truth's,
    the current's RMS error (m/s) against the truth at each row."""
    s = samples(paths)
    lat, lon, t = np.radians(s["lat"]), np.radians(s["lon"]), s["t"]
    dx = np.diff(lon) * np.cos(lat[:-1]) * EARTH_R
    dy = np.diff(lat) * EARTH_R
    dt = np.diff(t)
    ok = dt > 0.2
    speed = np.hypot(dx, dy)[ok] / dt[ok]
    sog = 0.5 * (s["sog"][:-1] + s["sog"][1:])[ok]
    dspeed = np.abs(speed - sog)
    dspeed = dspeed[np.isfinite(dspeed)]
    tt = truth["t"]
    has_yaw = np.isfinite(s["yaw_rate"])
    yaw = np.abs(s["yaw_rate"][has_yaw])
    true_yaw = np.interp(t[has_yaw], tt, truth["yaw_rate"])  # the truth at the rows' instants
    ce = np.interp(t, tt, truth["current_east"])
    cn = np.interp(t, tt, truth["current_north"])
    err = np.hypot(s["current_east"] - ce, s["current_north"] - cn)
    err = err[np.isfinite(err)]
    return {
        "rows": len(t),
        "speed_vs_sog_p95": float(np.percentile(dspeed, 95)),
        "yaw_rate_p99": float(np.percentile(yaw, 99)),
        "truth_yaw_rate_p99": float(np.percentile(np.abs(true_yaw), 99)),
        "yaw_rate_error_p99": float(np.percentile(np.abs(s["yaw_rate"][has_yaw] - true_yaw), 99)),
        "current_rmse": float(math.sqrt(np.mean(err**2))),
        "current_rows": len(err),
    }
