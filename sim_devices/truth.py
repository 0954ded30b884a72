"""Ground truth beside a simulated survey: effects.json, fields.npz and samples.csv (docs/CONVENTIONS.md)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from .fields import World

COLUMNS = (
    "t", "x", "y", "lat", "lon", "heading", "yaw_rate", "sog", "cog", "boat_east", "boat_north",
    "depth", "water_temp", "wind_east", "wind_north", "wind_speed", "wind_dir", "current_east",
    "current_north", "current_speed", "current_dir", "wheel1_speed", "wheel2_speed", "wheel3_speed",
    "wheel4_speed", "app_wind_speed", "app_wind_angle",
)  # fmt: skip
FORMATS = {"t": "%.3f", "lat": "%.8f", "lon": "%.8f"}


def compass(east: np.ndarray, north: np.ndarray) -> np.ndarray:
    """Compass degrees [0, 360) of a vector's direction (where it points TO)."""
    return np.degrees(np.arctan2(east, north)) % 360.0


def write_samples(path: Path, table: np.ndarray) -> None:
    fmt = [FORMATS.get(c, "%.4f") for c in COLUMNS]
    np.savetxt(path, table, delimiter=",", fmt=fmt, header=",".join(COLUMNS), comments="")


def write_fields(
    path: Path, world: World, t0: float, duration_s: float, nx: int = 121, ny: int = 41
) -> None:
    """The true fields on a grid: depth static, current and wind about once a minute."""
    x, y = world.grid(nx, ny)
    xx, yy = np.meshgrid(x, y)
    nt = int(min(61, max(2, math.ceil(duration_s / 60.0) + 1)))
    ts = np.linspace(0.0, duration_s, nt)
    ce = np.empty((nt, ny, nx), np.float32)
    cn, we, wn = np.empty_like(ce), np.empty_like(ce), np.empty_like(ce)
    for i, t in enumerate(ts):
        tt = np.full_like(xx, t)
        ce[i], cn[i] = world.current(xx, yy, tt)
        we[i], wn[i] = world.wind(xx, yy, tt)
    np.savez_compressed(
        path, x=x, y=y, t=t0 + ts, depth=world.depth(xx, yy).astype(np.float32),
        current_east=ce, current_north=cn, wind_east=we, wind_north=wn,
    )  # fmt: skip


def write_all(truth_dir: str | Path, meta: dict[str, Any], world: World, table: np.ndarray) -> Path:
    """Write the three truth files into ``truth_dir`` (created if needed)."""
    d = Path(truth_dir)
    d.mkdir(parents=True, exist_ok=True)
    (d / "effects.json").write_text(json.dumps(meta, indent=2, default=float) + "\n")
    write_fields(d / "fields.npz", world, float(meta["t0"]), float(meta["duration"]))
    write_samples(d / "samples.csv", table)
    return d
