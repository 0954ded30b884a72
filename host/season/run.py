"""A season from its logs: footprints, the common frame, one statistics pass (map + tree reduction), the
models, the staleness curve and (optionally) the depth map's blocked CV. The runner decides where the per-log
work runs (`engine`); everything after the reduction works on m x m matrices in this process."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.season.engine import LocalRunner
from forcemap.host.season.frame import choose_frame
from forcemap.host.season.model import (
    CurrentFit,
    StaticFit,
    fit_current,
    fit_depth,
)
from forcemap.host.season.staleness import Staleness, staleness
from forcemap.host.season.tasks import (
    Bundle,
    Frame,
    Rejected,
    SurveyResult,
    depth_cv,
    footprint,
    survey_stats,
)
from forcemap.host.workbench.errors import WorkbenchError

DEFAULT_BASIS = 400
WIND_BASIS = 64


@dataclass
class Season:
    frame: Frame
    surveys: list[SurveyResult]
    rejected: list[Rejected]
    total: Bundle
    depth: StaticFit | None
    current: CurrentFit | None
    wind: list
    stale: Staleness | None
    cv: list[dict] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    runner: str = "one process"


def run_season(
    paths: list[str],
    runner=None,
    n_basis: int = DEFAULT_BASIS,
    offsets: bool | None = None,
    cv: bool = True,
    progress=None,
    levels: bool | None = None,
    gauge=None,
) -> Season:
    """`levels`: one water level per survey in the depth model (True / False, None: the evidence decides);
    `gauge` (a `workbench.water_level.Gauge`): every log's depth reduced to its datum first."""
    runner = runner or LocalRunner()
    paths = [str(p) for p in paths]
    tm: dict[str, float] = {}
    t = time.perf_counter()
    fps = runner.map(footprint, paths, progress=_step(progress, "reading footprints"))
    rejected = [f for f in fps if isinstance(f, Rejected)]
    good = [f for f in fps if not isinstance(f, Rejected)]
    if not good:
        raise WorkbenchError(
            "no usable log in the season: " + "; ".join(r.reason for r in rejected)
        )
    frame, acc, far = choose_frame(good, n_basis, WIND_BASIS)
    frame.gauge = gauge
    rejected += far
    tm["footprints_s"] = time.perf_counter() - t
    t = time.perf_counter()
    results, total = runner.map_reduce(
        survey_stats, [f.path for f in acc], frame, progress=_step(progress, "statistics")
    )
    tm["statistics_s"] = time.perf_counter() - t
    rejected += [r for r in results if isinstance(r, Rejected)]
    surveys = [r for r in results if isinstance(r, SurveyResult)]
    if not surveys:
        raise WorkbenchError(
            "no usable log in the season: " + "; ".join(r.reason for r in rejected)
        )
    order = np.argsort([s.t0 for s in surveys], kind="stable")
    surveys = [surveys[i] for i in order]
    t = time.perf_counter()
    depth = fit_depth(frame, total, surveys, levels)
    tm["depth_s"] = time.perf_counter() - t
    current = fit_current(frame, surveys, offsets)
    tm["current_s"] = time.perf_counter() - t - tm["depth_s"]
    wind = [s.wind for s in surveys]
    stale = None
    if current is not None and len(current.own) >= 2:
        cur = [s for s in surveys if s.has["current_east"] and s.has["current_north"]]
        stale = staleness(
            np.array([s.t_mid for s in cur]),
            current.scales,
            current.own,
            [s.stats["current"] for s in cur],
        )
    tm["models_s"] = time.perf_counter() - t
    tm["staleness_s"] = tm["models_s"] - tm["depth_s"] - tm["current_s"]
    season = Season(
        frame, surveys, rejected, total, depth, current, wind, stale, runner=runner.name
    )
    if cv and depth is not None and len(surveys) >= 2:
        t = time.perf_counter()
        out = runner.map(
            depth_cv, [s.path for s in surveys if s.has["depth"]], frame, depth,
            progress=_step(progress, "depth blocked CV"),
        )  # fmt: skip
        season.cv = [r for r in out if isinstance(r, dict)]
        tm["depth_cv_s"] = time.perf_counter() - t
    season.timings = tm
    return season


def _step(progress, what: str):
    if progress is None:
        return None
    return lambda i, n: progress(f"{what}: {i} of {n}")
