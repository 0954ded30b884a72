"""Ground truth beside a simulated survey: effects.json, fields.npz and samples.csv (docs/CONVENTIONS.md)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel.geodesy import LocalFrame

from .fields import World

COLUMNS = (
    "t", "x", "y", "lat", "lon", "heading", "yaw_rate", "sog", "cog", "boat_east", "boat_north",
    "depth", "water_temp", "wind_east", "wind_north", "wind_speed", "wind_dir", "current_east",
    "current_north", "current_speed", "current_dir", "wheel1_speed", "wheel2_speed", "wheel3_speed",
    "wheel4_speed", "app_wind_speed", "app_wind_angle", "water_level", "roll",
)  # fmt: skip
FORMATS = {"t": "%.3f", "lat": "%.8f", "lon": "%.8f"}
# the simulation's per-step rows and extras, in order
TRACK = ("t", "x", "y", "heading", "yaw_rate", "sog", "boat_east", "boat_north", "depth",
         "water_temp", "wind_east", "wind_north", "current_east", "current_north", "wheel1_speed",
         "wheel2_speed", "wheel3_speed", "wheel4_speed", "app_wind_speed", "app_wind_angle")  # fmt: skip
EXTRA = ("xte", "leg", "throttle", "u", "v", "roll")


def compass(east: np.ndarray, north: np.ndarray) -> np.ndarray:
    """Compass degrees [0, 360) of a vector's direction (where it points TO)."""
    return np.degrees(np.arctan2(east, north)) % 360.0


def track_arrays(rows: list, extra: list) -> dict[str, np.ndarray]:
    """The true track by column (``TRACK`` and ``EXTRA``) from the simulation's recorded rows."""
    if not rows:
        return {}
    r, e = np.array(rows), np.array(extra)
    out = {n: r[:, i] for i, n in enumerate(TRACK)}
    out.update({n: e[:, i] for i, n in enumerate(EXTRA)})
    return out


def samples_table(track: dict[str, np.ndarray], geo: LocalFrame, t0: float) -> np.ndarray:
    """The samples.csv table from the true track: columns as ``COLUMNS``, UNIX time from ``t0``."""
    if not track:
        return np.empty((0, len(COLUMNS)))
    lat, lon = geo.to_latlon(track["x"], track["y"])
    cols = {
        **track,
        "t": t0 + track["t"],
        "lat": lat,
        "lon": lon,
        "cog": compass(track["boat_east"], track["boat_north"]),
        "wind_speed": np.hypot(track["wind_east"], track["wind_north"]),
        "wind_dir": compass(-track["wind_east"], -track["wind_north"]),
        "current_speed": np.hypot(track["current_east"], track["current_north"]),
        "current_dir": compass(track["current_east"], track["current_north"]),
        "water_level": track.get("water_level", np.zeros(len(track["t"]))),
    }
    return np.column_stack([cols[c] for c in COLUMNS])


def write_pulses(path: Path, boots: list[tuple[int, int]], pulses: list[list[int]]) -> None:
    """The pulse ledger: every real pulse on each bridge channel, and each boot's start, on the
    bridge's timeline in µs (a frame's timeline time is its boot's ``boot_us`` + ``t_us``)."""
    np.savez_compressed(
        path,
        boot_id=np.array([b for b, _ in boots], dtype=np.uint64),
        boot_us=np.array([u for _, u in boots], dtype=np.int64),
        **{f"ch{ch}": np.array(t, dtype=np.int64) for ch, t in enumerate(pulses)},
    )


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
        water_level=np.asarray(world.water_level(ts), float) + np.zeros(nt),
        current_east=ce, current_north=cn, wind_east=we, wind_north=wn,
    )  # fmt: skip


def write_all(truth_dir: str | Path, meta: dict[str, Any], world: World, table: np.ndarray) -> Path:
    """Write the three truth files into ``truth_dir`` (created if needed)."""
    d = Path(truth_dir)
    d.mkdir(parents=True, exist_ok=True)
    (d / "effects.json").write_text(json.dumps(meta, indent=2, default=float) + "\n")
    write_fields(d / "fields.npz", world, float(meta["t0"]), float(meta["duration"]))
    write_samples(d / "samples.csv", table)
    if len(table):
        write_gauge(d / "water_level.csv", world, float(meta["t0"]), float(meta["duration"]))
    return d


def write_gauge(
    path: Path, world: World, t0: float, duration_s: float, every_s: float = 60.0
) -> None:
    """The true water level as a gauge would log it: `time,level_m` (UNIX s, m above the surface at rest)
    every `every_s`, over the survey and a step either side (a file for `--water-level`)."""
    ts = np.arange(-every_s, duration_s + 2 * every_s, every_s)
    level = np.asarray(world.water_level(ts), float) + np.zeros(len(ts))
    rows = np.column_stack([t0 + ts, level])
    np.savetxt(path, rows, delimiter=",", fmt=["%.3f", "%.4f"], header="time,level_m", comments="")


def effects_meta(sim: Any) -> dict[str, Any]:
    """What effects.json holds about a finished `engine.Simulation`."""
    return {
        "scenario": sim.scenario.name,
        "scenario_path": sim.scenario.path,
        "mission": sim.mission.name,
        "seed": sim.seed,
        "lat0": sim.scenario.lat0,
        "lon0": sim.scenario.lon0,
        "t0": sim.scenario.t0,
        "duration": sim.t,
        "effects": [
            {"name": e.name, "kind": e.spec.kind, "story": e.spec.story, "params": e.params}
            for e in sim.effects
        ],
        "faults": [f.resolved(sim.duration) for f in sim.faults],
        "fault_log": [{"t": t, "action": a, "source": s} for t, a, s in sim.fault_log],
        "instruments": {
            "wheel_angles_deg": list(sim.sensors.cfg.wheel_angles_deg),
            "wheel_pulses_per_m": list(sim.sensors.cfg.wheel_pulses_per_m),
            "anemo_hz_per_mps": sim.sensors.cfg.anemo_hz_per_mps,
            "bridge_clock_ppm": sim.ppm,
            "mavlink_latency_s": sim.mav_latency_ns * 1e-9,
            "sounder_offset_m": sim.sounder.offset,
            "sounder_noise_m": sim.sounder.noise,
            "false_echoes": sim.sounder.false_echoes,
            "bottom_lost_soundings": sim.sounder.lost_soundings,
            "bottom_lost_stretches": _stretches(sim.sounder.lost_times),
            "sounder_beam_deg": sim.sounder.beam_deg,
            "sounder_range_m": sim.sounder.rough_range,
            "nmea_bus": sorted(sim.bus_faults) if sim.nmea_bus else None,
        },
    }


def _stretches(times: list[float], gap: float = 1.5) -> list[list[float]]:
    """Runs of soundings (s since the start) no more than ``gap`` apart: [first, last] of each."""
    out: list[list[float]] = []
    for t in times:
        if out and t - out[-1][1] <= gap:
            out[-1][1] = t
        else:
            out.append([t, t])
    return out


def write_mission(folder: Path, mission: ms.Mission, frame: LocalFrame) -> None:
    """mission.waypoints, the mission flown (QGC WPL 110), and mission.json with its intended lines."""
    ms.save_waypoints(folder / "mission.waypoints", mission, frame)
    (folder / "mission.json").write_text(json.dumps(ms.to_json(mission, frame), indent=1) + "\n")
