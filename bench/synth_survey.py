"""A small synthetic river survey with known hidden effects in closed form: the GP benchmark's data and the CLI tests'
table, made in a second where the simulator (`forcemap.sim_devices.offline.make_survey`, which the effect tests
and the diagnosis benchmark use) runs the instruments and the daemon's pipeline.

`make_survey(scenario, effects, seed, duration_s, out_dir)` has the simulator's signature and writes a samples table (CSV, the columns of docs/CONVENTIONS.md) with a
`truth/effects.json` beside it. The boat is kinematic: it holds 3.5 m/s through the water, crabs to keep a
lawnmower track parallel to the flow, and turns at a limited rate, so sog, cog and the crab angle respond to the
current exactly as on the water. With `held_throttle` the throttle is set once per leg (a different setting on
each leg) and held: the speed through the water follows it, the ground speed follows the current too, and the
`throttle` column records the setting.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
from pathlib import Path

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame

EFFECTS = (
    "depth_current",
    "dam_release",
    "gusts",
    "bank_shelter",
    "wheel_misalignment",
    "anemometer_upwash",
    "compass_deviation",
    "clock_offset",
)
LAT0, LON0, T0 = 33.95, -81.05, 1_700_000_000.0
HALF_LENGTH, HALF_WIDTH = 300.0, 75.0
BOAT_SPEED = 3.5
MAX_TURN_RATE = 20.0  # deg/s
RATE_HZ = 1.0


def depth_field(x, y):
    """Thalweg meandering along the reach, plus sand bars of ~60 m: 0.5-6 m."""
    centre = 25.0 * np.sin(2 * np.pi * x / 500.0)
    channel = 4.5 * np.exp(-(((y - centre) / 45.0) ** 2))
    bars = 1.1 * np.sin(2 * np.pi * x / 60.0 + 0.7) * np.cos(2 * np.pi * y / 45.0)
    return np.clip(0.8 + channel + bars, 0.5, 6.0)


def current_field(x, y, t, effects, duration):
    """Velocity of the water (m/s east, north): down the reach (east), strongest mid-channel."""
    centre = 25.0 * np.sin(2 * np.pi * x / 500.0)
    speed = 1.2 + 0.8 * np.exp(-(((y - centre) / 60.0) ** 2))
    if "depth_current" in effects:
        d = depth_field(x, y)
        speed = speed * 0.85 * (d / 3.0) ** (2.0 / 3.0)
    if "dam_release" in effects:
        speed = speed * (0.75 + 0.5 / (1 + np.exp(-(t - 0.5 * duration) / (0.12 * duration))))
    slope = 25.0 * 2 * np.pi / 500.0 * np.cos(2 * np.pi * x / 500.0)
    ang = np.arctan(slope)
    return speed * np.cos(ang), speed * np.sin(ang)


def wind_field(x, y, t, effects, duration, rng_phase):
    """Velocity of the air (m/s east, north). Wind FROM ~250 deg, 7 m/s, gently varying in space."""
    from_dir = 250.0 + 8.0 * np.sin(x / 200.0)
    if "bank_shelter" in effects:
        from_dir = 200.0 + 200.0 * (t / duration)  # veers from SSW through W to NNE
    speed = 7.0 + 0.6 * np.cos(y / 60.0 + 0.3) + 0.4 * np.sin(x / 150.0)
    if "gusts" in effects:
        g = sum(
            np.sin(2 * np.pi * t / p + ph)
            for p, ph in zip((900.0, 1500.0, 2300.0), rng_phase, strict=True)
        )
        speed = speed * (1.0 + 0.12 * g)
    if "bank_shelter" in effects:
        from_north = np.clip(np.cos(np.radians(from_dir)), 0.0, None)
        lee = np.exp(-(HALF_WIDTH - y) / 70.0)
        speed = speed * (1.0 - 0.85 * from_north * lee)
    rad = np.radians(from_dir)
    return -speed * np.sin(rad), -speed * np.cos(rad)


def _waypoints(spacing: float = 15.0) -> list[tuple[float, float]]:
    ys = np.arange(-HALF_WIDTH + 10.0, HALF_WIDTH - 9.0, spacing)
    pts = []
    for i, yy in enumerate(ys):
        xs = (-HALF_LENGTH + 15.0, HALF_LENGTH - 15.0)
        if i % 2:
            xs = xs[::-1]
        pts += [(xs[0], yy), (xs[1], yy)]
    return pts


def _track(rng, effects: set[str], duration_s: float, rate_hz: float, held_throttle: bool):
    """Fly the lawnmower from a random start: true positions, headings, ground velocities, currents and
    throttle settings."""
    dt = 1.0 / rate_hz
    n = int(duration_s * rate_hz)
    wps = _waypoints()
    start = int(rng.integers(0, len(wps) // 2)) * 2
    wps = wps[start:] + wps[:start]
    p = np.array(wps[0], float)
    h = 90.0 if wps[1][0] > wps[0][0] else 270.0
    k = 1
    # throttle per leg (fraction of the nominal setting) when it is held, else the nominal one
    leg_throttle = rng.uniform(0.75, 1.25, 64) if held_throttle else np.ones(1)
    P, H, VB, C = np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty((n, 2))
    THR = np.empty(n)
    for i in range(n):
        ce, cn = current_field(p[0], p[1], i * dt, effects, duration_s)
        c = np.array([float(ce), float(cn)])
        target = np.array(wps[k % len(wps)])
        to = target - p
        if np.hypot(*to) < 8.0:
            k += 1
            target = np.array(wps[k % len(wps)])
            to = target - p
        throttle = leg_throttle[k % len(leg_throttle)]
        stw = BOAT_SPEED * throttle
        h = _steer(h, to, c, dt, stw)
        hv = np.array([math.sin(math.radians(h)), math.cos(math.radians(h))])
        vb = stw * hv + c
        P[i], H[i], VB[i], C[i], THR[i] = p, h, vb, c, 55.0 * throttle
        p = p + vb * dt
    return P, H, VB, C, THR


def _steer(h: float, to: np.ndarray, c: np.ndarray, dt: float, stw: float) -> float:
    """The new heading: crab into the cross-track current to hold the line, at a limited turn rate."""
    d = to / max(np.hypot(*to), 1e-9)
    perp = np.array([d[1], -d[0]])
    s = np.clip(-(c @ perp) / stw, -0.9, 0.9)
    course = math.degrees(math.atan2(d[0], d[1]))
    desired = course + math.degrees(math.asin(s))
    err = (desired - h + 180.0) % 360.0 - 180.0
    return (h + float(np.clip(err, -MAX_TURN_RATE * dt, MAX_TURN_RATE * dt))) % 360.0


def _rotate(v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Rotate (east, north) rows clockwise by `a` radians (into a frame turned by a compass error)."""
    return np.column_stack(
        [v[:, 0] * np.cos(a) + v[:, 1] * np.sin(a), -v[:, 0] * np.sin(a) + v[:, 1] * np.cos(a)]
    )


def _water_and_ground(rng, effects, H, VB, C, dh, rate_hz):
    """Measured water relative to the hull (paddle wheels), ground velocity, and the current from them."""
    n = len(H)
    F_meas = _rotate(C - VB, dh) + 0.06 * rng.standard_normal((n, 2))
    if "wheel_misalignment" in effects:
        starboard = np.column_stack([np.cos(np.radians(H)), -np.sin(np.radians(H))])
        F_meas = F_meas + 0.42 * starboard  # a wheel ~7 deg off: 0.42 m/s across the bow at 3.5 m/s
    vb_meas = VB + 0.03 * rng.standard_normal((n, 2))
    vb_used = vb_meas
    if "clock_offset" in effects:
        shift = int(round(1.0 * rate_hz)) or 1
        vb_used = np.vstack([vb_meas[:1].repeat(shift, axis=0), vb_meas[:-shift]])
    return F_meas, vb_meas, F_meas + vb_used


def _air(rng, effects, x, y, t, VB, dh, phase, duration_s):
    """Measured air relative to the boat (the anemometer)."""
    W = np.column_stack(wind_field(x, y, t, effects, duration_s, phase))
    R_meas = _rotate(W - VB, dh) + 0.25 * rng.standard_normal((len(t), 2))
    if "anemometer_upwash" in effects:
        R_meas = R_meas * (1.0 + 0.09 * np.hypot(VB[:, 0], VB[:, 1]))[:, None]
    return R_meas


def _wheels(F_meas: np.ndarray, h_meas: np.ndarray) -> dict[str, np.ndarray]:
    """Speeds of the four wheels at 45, 135, 225 and 315 deg, from the water relative to the hull."""
    F_boat = _rotate(F_meas, np.radians(h_meas))  # (starboard, forward) components
    axes = np.radians([45.0, 135.0, 225.0, 315.0])
    return {
        f"wheel{i + 1}_speed": np.abs(F_boat[:, 0] * np.sin(a) + F_boat[:, 1] * np.cos(a))
        for i, a in enumerate(axes)
    }


# the sounder's noise (m, 1 sd): what a depth map's noise should come back as
DEPTH_NOISE = 0.05


def false_echoes(depth: np.ndarray, rng, rate: float) -> np.ndarray:
    """Rows (a share `rate` of them, in short runs of 1-3 like a fish school or a thermocline) whose
    sounding is a false shallow echo: 3 to 20 m in deep water, 10-60 % of the depth in shallow water."""
    n = len(depth)
    starts = rng.choice(n, size=max(1, int(rate * n / 2)), replace=False)
    runs = rng.integers(1, 4, len(starts))
    rows = np.unique(np.concatenate([s + np.arange(k) for s, k in zip(starts, runs, strict=True)]))
    return rows[rows < n]


def echo_stretch(n: int, rng, stretch: tuple[float, float, float]) -> np.ndarray:
    """Rows of a stretch (its start and end as shares of the survey) where each sounding is a false
    echo with probability `rate`: above 0.5, the echoes are the local majority."""
    lo, hi, rate = stretch
    rows = np.arange(int(lo * n), int(hi * n))
    return rows[rng.random(len(rows)) < rate]


def _echo_values(depth: np.ndarray, rows: np.ndarray, rng) -> np.ndarray:
    d = depth[rows]
    return np.where(
        d > 30.0, rng.uniform(3.0, 20.0, len(rows)), d * rng.uniform(0.1, 0.6, len(rows))
    )


def simulate(
    effects=(),
    seed=0,
    duration_s=2400.0,
    rate_hz=RATE_HZ,
    held_throttle=False,
    deep_m=0.0,
    false_echo_rate=0.0,
    echo_stretch_at: tuple[float, float, float] | None = None,
) -> dict[str, np.ndarray]:
    """Run the lawnmower mission and return the samples-table columns. `deep_m` adds that much water
    under the whole reach (a deep-water survey); `false_echo_rate` replaces that share of the soundings
    by false shallow echoes (their rows are in the returned ``_false_echo_rows``, not a column);
    `echo_stretch_at` = (start, end, rate) adds a stretch where they are `rate` of the soundings."""
    rng = np.random.default_rng(seed)
    effects = set(effects)
    unknown = effects - set(EFFECTS)
    if unknown:
        raise ValueError(f"unknown effect(s): {sorted(unknown)}")
    phase = rng.uniform(0, 2 * np.pi, 3)
    P, H, VB, C, THR = _track(rng, effects, duration_s, rate_hz, held_throttle)
    n, dt = len(H), 1.0 / rate_hz
    t = np.arange(n) * dt
    x, y = P[:, 0], P[:, 1]
    yaw_rate = np.degrees(np.gradient(np.unwrap(np.radians(H))) / dt)
    h_meas = H.copy()
    if "compass_deviation" in effects:
        h_meas = (H + 7.0 * np.sin(np.radians(H + 40.0))) % 360.0
    dh = np.radians(h_meas - H)
    F_meas, vb_meas, C_meas = _water_and_ground(rng, effects, H, VB, C, dh, rate_hz)
    R_meas = _air(rng, effects, x, y, t, VB, dh, phase, duration_s)
    W_meas = R_meas + vb_meas
    depth = deep_m + depth_field(x, y) + DEPTH_NOISE * rng.standard_normal(n)
    app_from = np.degrees(np.arctan2(-R_meas[:, 0], -R_meas[:, 1]))
    lat, lon = LocalFrame(LAT0, LON0).to_latlon(x, y)
    lat = lat + 2e-6 * rng.standard_normal(n) * 0.1
    cols = {
        "t": T0 + t,
        "lat": lat,
        "lon": lon,
        "heading": h_meas,
        "yaw_rate": yaw_rate + 0.3 * rng.standard_normal(n),
        "sog": np.hypot(vb_meas[:, 0], vb_meas[:, 1]),
        "cog": np.degrees(np.arctan2(vb_meas[:, 0], vb_meas[:, 1])) % 360.0,
        "depth": depth,
        "water_temp": 18.0
        + 0.4 * np.sin(x / 250.0)
        + 0.002 * t / 60.0
        + 0.02 * rng.standard_normal(n),
        "wind_speed": np.hypot(W_meas[:, 0], W_meas[:, 1]),
        "wind_dir": np.degrees(np.arctan2(-W_meas[:, 0], -W_meas[:, 1])) % 360.0,
        "wind_east": W_meas[:, 0],
        "wind_north": W_meas[:, 1],
        "app_wind_speed": np.hypot(R_meas[:, 0], R_meas[:, 1]),
        "app_wind_angle": (app_from - h_meas + 180.0) % 360.0 - 180.0,
        "current_speed": np.hypot(C_meas[:, 0], C_meas[:, 1]),
        "current_dir": np.degrees(np.arctan2(C_meas[:, 0], C_meas[:, 1])) % 360.0,
        "current_east": C_meas[:, 0],
        "current_north": C_meas[:, 1],
        **_wheels(F_meas, h_meas),
        "throttle": THR + 2.0 * rng.standard_normal(n),
    }
    rows = np.zeros(0, int)
    if false_echo_rate > 0:  # drawn after everything else: the other columns stay the same
        rows = false_echoes(depth, rng, false_echo_rate)
    if echo_stretch_at is not None:
        rows = np.union1d(rows, echo_stretch(n, rng, echo_stretch_at))
    if len(rows):
        cols["depth"][rows] = _echo_values(depth, rows, rng)
        cols["_false_echo_rows"] = rows
    return cols


def make_survey(
    scenario: str,
    effects: list[str],
    seed: int,
    duration_s: float,
    out_dir,
    held_throttle: bool = False,
    extra: dict | None = None,
    deep_m: float = 0.0,
    false_echo_rate: float = 0.0,
    echo_stretch_at: tuple[float, float, float] | None = None,
) -> Path:
    """Write `survey.csv` and `truth/effects.json` into `out_dir`; return the CSV's path. `extra` maps more
    column names to functions of the columns (e.g. an instrument's ensemble counter)."""
    out = Path(out_dir)
    (out / "truth").mkdir(parents=True, exist_ok=True)
    cols = simulate(
        effects,
        seed,
        duration_s,
        held_throttle=held_throttle,
        deep_m=deep_m,
        false_echo_rate=false_echo_rate,
        echo_stretch_at=echo_stretch_at,
    )
    echo_rows = cols.pop("_false_echo_rows", np.zeros(0, int))
    for name, make in (extra or {}).items():
        cols[name] = np.asarray(make(cols), float)
    path = out / "survey.csv"
    names = list(cols)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for row in zip(*(cols[k] for k in names), strict=True):
            w.writerow([f"{v:.7f}" if abs(v) < 1e6 else f"{v:.3f}" for v in row])
    meta = {
        "scenario": scenario,
        "seed": seed,
        "effects": list(effects),
        "held_throttle": held_throttle,
        "lat0": LAT0,
        "lon0": LON0,
        "t0": T0,
        "duration": duration_s,
        "generator": "bench.synth_survey",
        "deep_m": deep_m,
        "depth_noise": DEPTH_NOISE,
        "false_echo_rows": [int(i) for i in echo_rows],
    }
    (out / "truth" / "effects.json").write_text(json.dumps(meta, indent=2))
    return path


def write_long_survey(
    path,
    n: int,
    rate_hz: float = 1.0,
    seed: int = 0,
    day_s: float = 86_400.0,
    moored_s: float = 3_600.0,
) -> Path:
    """A long survey of `n` rows at `rate_hz` (10^6 rows at 1 Hz: 12.1 days of 23 hours), written one day at a
    time as Parquet row groups (CSV when `path` ends in .csv): each day a lawnmower flown from a random start
    with its own noise (seed + day), after `moored_s` at the bank (no rows: the boat moves to the next day's
    start in that hour, not in a second). Memory holds one day's columns, never the whole table."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    per_day = int((day_s - moored_s) * rate_hz)
    writer, done, day = None, 0, 0
    with path.open("w", newline="") if path.suffix == ".csv" else contextlib.nullcontext() as f:
        while done < n:
            rows = min(per_day, n - done)
            cols = simulate([], seed + day, rows / rate_hz, rate_hz=rate_hz)
            cols["t"] = cols["t"] + day * day_s
            if f is not None:
                w = csv.writer(f)
                if day == 0:
                    w.writerow(list(cols))
                for row in zip(*cols.values(), strict=True):
                    w.writerow([f"{v:.7f}" for v in row])
            else:
                table = pa.table(cols)
                if writer is None:
                    writer = pq.ParquetWriter(path, table.schema)
                writer.write_table(table, row_group_size=65_536)
            done, day = done + rows, day + 1
    if writer is not None:
        writer.close()
    return path
