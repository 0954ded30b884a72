"""A season of offline surveys of one river: `forcemap sim --season N --days D -o DIR`.

Every survey is a lawnmower track over the scenario's survey box, sampled at 5 Hz, through the scenario's
world (`fields.World`): the depth is fixed (with an optional slow shift of the sand bars downstream), the
current is the scenario's pattern times the day's discharge, which follows a hydrograph (a rise to a peak at
a quarter of the season and a recession), and the wind's speed and direction change by day. The measured
values are the truth plus instrument noise; the tables go straight to Parquet (no instruments or daemon in
the loop: a season of 5 million samples takes seconds, not hours). With a stage (`stage_scale_m`), the water
surface follows the day's discharge through a rating curve and every sounding is deeper by it (`stage_m` in
each survey's truth). Each survey's truth is written beside it.

    DIR/survey-000/samples.parquet   DIR/survey-000/truth.json   ...   DIR/season_truth.json
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.vessel.scenario import load

from .fields import World, rating_stage

RATE_HZ = 5.0
SPEED_MPS = 3.5
LINES = 9
DAY_S = 86400.0
NOISE = {"depth": 0.05, "current": 0.08, "wind": 0.4}


@dataclass
class SurveyTruth:
    """What the simulator knows about one survey of the season."""

    index: int
    day: float  # days since the season's start (the survey's start)
    t_start: float  # UNIX s
    discharge_scale: float  # the current is the scenario's pattern times this
    wind_speed: float  # m/s, the day's reference speed
    wind_from_deg: float
    bar_shift_m: float  # how far the sand bars have moved downstream (+x)
    samples: int
    stage_m: float = (
        0.0  # the water surface above its level at discharge scale 1 (the rating curve)
    )


def hydrograph(day: np.ndarray | float, days: float) -> np.ndarray:
    """Discharge relative to the scenario's: base flow 0.6, a rise to 1.6 at a quarter of the season, then a
    recession (a gamma-shaped unit hydrograph)."""
    tp = max(days / 4.0, 1e-6)
    u = np.maximum(np.asarray(day, float), 0.0) / tp
    return 0.6 + 1.0 * u * np.exp(1.0 - u)


def lawnmower(n: int, box: tuple[float, float, float, float], rng: np.random.Generator):
    """`n` positions (and headings) at 5 Hz along a lawnmower of along-stream lines, repeated as needed."""
    x0, x1, y0, y1 = box
    jitter = rng.uniform(-0.4, 0.4) * (y1 - y0) / (LINES - 1)
    ys = np.clip(np.linspace(y0, y1, LINES) + jitter, y0, y1)
    corners = []
    for i, y in enumerate(ys):
        corners += [(x0, y), (x1, y)] if i % 2 == 0 else [(x1, y), (x0, y)]
    corners += corners[::-1][1:]
    pts = np.array(corners)
    seg = np.hypot(*np.diff(pts, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = (np.arange(n) * SPEED_MPS / RATE_HZ + rng.uniform(0, cum[-1])) % cum[-1]
    x, y = np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])
    k = np.minimum(np.searchsorted(cum, s, side="right") - 1, len(seg) - 1)
    d = pts[k + 1] - pts[k]
    heading = np.degrees(np.arctan2(d[:, 0], d[:, 1])) % 360.0
    return x, y, heading


def season_plan(
    n: int, days: float, seed: int, bar_shift_per_day: float, stage_scale_m: float = 0.0
) -> list[SurveyTruth]:
    """When each survey is flown and the river's state that day (with `stage_scale_m`, the stage follows
    the day's discharge through the rating curve `fields.rating_stage`)."""
    rng = np.random.default_rng([seed, 24])
    start = load("river").t0
    day = np.linspace(0.0, days, n) + rng.uniform(0, 0.1, n) if n > 1 else np.zeros(1)
    day = np.clip(day, 0.0, days)
    wind_speed = rng.uniform(3.0, 9.0, int(days) + 2)
    wind_from = rng.uniform(0.0, 360.0, int(days) + 2)
    out = []
    for i, d in enumerate(day):
        k = int(d)
        out.append(
            SurveyTruth(
                i,
                float(d),
                start + float(d) * DAY_S,
                float(hydrograph(d, days)),
                float(wind_speed[k]),
                float(wind_from[k]),
                float(bar_shift_per_day * d),
                0,
                float(rating_stage(hydrograph(d, days), stage_scale_m)),
            )
        )
    return out


def simulate_survey(truth: SurveyTruth, samples: int, seed: int) -> dict[str, np.ndarray]:
    """The samples table of one survey (measured values, UNIX time, lat/lon)."""
    sc = load("river")
    world = World(sc, [], samples / RATE_HZ, seed)
    world.bars = world.bars + np.array([truth.bar_shift_m, 0.0, 0.0, 0.0])
    world.w_speed = truth.wind_speed
    world.wind_from_deg = lambda t: truth.wind_from_deg + 0.0 * np.asarray(t, float)  # type: ignore[method-assign]
    rng = np.random.default_rng([seed, truth.index, 7])
    x, y, heading = lawnmower(samples, sc.survey_box, rng)
    t = np.arange(samples) / RATE_HZ
    ce, cn = world.current(x, y, t)
    we, wn = world.wind(x, y, t)
    cols = {
        "t": truth.t_start + t,
        "depth": world.depth(x, y) + truth.stage_m + rng.normal(0, NOISE["depth"], samples),
        "current_east": truth.discharge_scale * ce + rng.normal(0, NOISE["current"], samples),
        "current_north": truth.discharge_scale * cn + rng.normal(0, NOISE["current"], samples),
        "wind_east": we + rng.normal(0, NOISE["wind"], samples),
        "wind_north": wn + rng.normal(0, NOISE["wind"], samples),
        "heading": heading,
        "sog": np.full(samples, SPEED_MPS),
    }
    cols["lat"], cols["lon"] = LocalFrame(sc.lat0, sc.lon0).to_latlon(x, y)
    for v in ("current", "wind"):
        e, n = cols[f"{v}_east"], cols[f"{v}_north"]
        cols[f"{v}_speed"] = np.hypot(e, n)
        to = np.degrees(np.arctan2(e, n)) % 360.0
        cols[f"{v}_dir"] = (to + 180.0) % 360.0 if v == "wind" else to
    return cols


def write_table(cols: dict[str, np.ndarray], path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({k: np.asarray(v, float) for k, v in cols.items()}), path)


def make_season(
    n: int,
    days: float,
    out_dir: str | Path,
    *,
    samples: int = 54_000,
    seed: int = 0,
    bar_shift_per_day: float = 0.0,
    stage_scale_m: float = 0.0,
    progress=None,
) -> list[Path]:
    """Write `n` surveys over `days` days into `out_dir`; returns the tables' paths. `stage_scale_m` above
    0 moves the water surface with the discharge (a rating curve, `fields.rating_stage`): 0.98 m gives the
    hydrograph's 0.6-1.6 discharge a 0.6 m stage range."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plan = season_plan(n, days, seed, bar_shift_per_day, stage_scale_m)
    paths = []
    for truth in plan:
        folder = out / f"survey-{truth.index:03d}"
        folder.mkdir(exist_ok=True)
        cols = simulate_survey(truth, samples, seed)
        truth.samples = samples
        write_table(cols, folder / "samples.parquet")
        (folder / "truth.json").write_text(json.dumps(asdict(truth), indent=1) + "\n")
        paths.append(folder / "samples.parquet")
        if progress:
            progress(truth.index + 1, n)
    meta = {
        "scenario": "river",
        "days": days,
        "seed": seed,
        "bar_shift_m_per_day": bar_shift_per_day,
        "noise_std": NOISE,
        "hydrograph": "0.6 + u exp(1 - u), u = day / (days / 4)",
        "rating": f"stage_m = {stage_scale_m} (discharge_scale^(1/1.6) - 1)",
        "surveys": [asdict(t) for t in plan],
    }
    (out / "season_truth.json").write_text(json.dumps(meta, indent=1) + "\n")
    return paths


def true_fields(xy: np.ndarray, bar_shift_m: float = 0.0) -> dict[str, np.ndarray]:
    """The true depth and the current at discharge scale 1 at local positions `xy` (scenario frame)."""
    world = World(load("river"), [], 1.0, 0)
    world.bars = world.bars + np.array([bar_shift_m, 0.0, 0.0, 0.0])
    ce, cn = world.current(xy[:, 0], xy[:, 1], 0.0)
    return {"depth": world.depth(xy[:, 0], xy[:, 1]), "current_east": ce, "current_north": cn}
