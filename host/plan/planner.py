"""The whole plan: predict the original mission, adjust it, predict again, and say per line how each does.

Per intended line it reports the predicted distance from the line (p95 and worst), time on the line,
coverage, the stretches where the current is at least the boat's top speed through the water (no
headway), and how much the prediction moves when the mapped current is scaled by its uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .adjust import Plan, adjust, original_plan
from .boat_model import BoatModel
from .maps import Maps
from .metrics import TOL_M, LineScore, score_lines, stretches, summary
from .predict import Track, predict_track

SIGMAS = 2.0  # the current scaled by 1 +- SIGMAS x its relative map uncertainty
# a mission is left unchanged only if it would also hold its lines in a current this much stronger: a map
# from a calmer day must not talk the planner out of compensating (a river's discharge varies by more
# than its map's uncertainty)
STRESS = 1.5
COVERAGE = 0.95  # the share of a line within TOL_M of the track that counts as holding it


@dataclass
class Outcome:
    """A mission and its predicted track, scored on the intended lines."""

    plan: Plan
    track: Track
    scores: list[LineScore]

    def to_json(self) -> dict:
        return {
            "duration_s": self.track.duration,
            "stuck_at_waypoint": self.track.stuck_at,
            **summary(self.scores),
            "lines": [s.to_json() for s in self.scores],
        }


@dataclass
class PlanResult:
    original: Outcome
    planned: Outcome
    no_headway: list[
        list[tuple[float, float]]
    ]  # per line, stretches (from, to) in m along the line
    sensitivity: dict = field(default_factory=dict)
    current_scale_sd: float = 0.0
    current_cv_rmse: float = 0.0  # m/s, the current map's blocked-CV RMSE per component
    unchanged: bool = False  # the original already held its lines and is kept as it is

    def to_json(self) -> dict:
        return {
            "original": self.original.to_json(),
            "planned": self.planned.to_json(),
            "no_headway_m": self.no_headway,
            "current_relative_sd": self.current_scale_sd,
            "current_cv_rmse_m_s": self.current_cv_rmse,
            "unchanged": self.unchanged,
            "sensitivity": self.sensitivity,
        }


def outcome(
    plan: Plan, maps: Maps, boat: BoatModel, track: Track | None = None, scale: float = 1.0
) -> Outcome:
    track = track or predict_track(plan.wps, plan.speeds, maps, boat, current_scale=scale)
    return Outcome(plan, track, score_lines(track.t, track.xy, plan.lines))


def line_times(track: Track, lines: np.ndarray, t_start: float | None) -> list[float | None]:
    """When the predicted track passes each line's middle (UNIX s; None without a start time)."""
    if t_start is None or not len(track.t):
        return [None] * len(lines)
    mids = lines.mean(axis=1)
    k = [int(np.argmin(np.hypot(*(track.xy - m).T))) for m in mids]
    return [t_start + float(track.t[i]) for i in k]


def no_headway(
    lines: np.ndarray, maps: Maps, boat: BoatModel, when: list[float | None] | None = None
) -> list[list[tuple[float, float]]]:
    """Stretches of each line where the mapped current against it (when the boat is there: `when`) is at
    least the boat's top speed."""
    out = []
    for i, (a, b) in enumerate(lines):
        d = b - a
        length = float(np.hypot(*d))
        s = np.linspace(0.0, length, max(int(length / 2.0), 2))
        e, n, _ = maps.current.sample(a + (s / length)[:, None] * d, when[i] if when else None)
        against = -(e * d[0] + n * d[1]) / length
        out.append(stretches(against >= boat.max_speed, s))
    return out


def relative_sd(lines: np.ndarray, maps: Maps, when: list[float | None] | None = None) -> float:
    """The map's current uncertainty relative to its speed along the lines (each at its time `when`, for a
    field in time): the larger of its predictive sd there (what a new measurement would differ by, not the
    mean's sd alone) and its blocked-CV RMSE."""
    pts = np.concatenate([a + np.linspace(0, 1, 50)[:, None] * (b - a) for a, b in lines])
    t = None
    if when is not None and all(w is not None for w in when):
        t = np.repeat(np.asarray(when, float), 50)
    e, n, sd = maps.current.sample(pts, t)
    speed = np.hypot(e, n)
    spread = max(float(np.mean(sd)), maps.current.cv_rmse)
    return spread / max(float(np.mean(speed)), 1e-6) if speed.mean() > 0.05 else 0.0


def _deltas(sc: list[LineScore], base: Outcome, duration: float) -> dict:
    return {
        **summary(sc),
        "duration_s": duration,
        "delta_p95_per_line": [
            round(s.p95 - b.p95, 3) for s, b in zip(sc, base.scores, strict=True)
        ],
        "delta_coverage_per_line": [
            round(s.coverage - b.coverage, 4) for s, b in zip(sc, base.scores, strict=True)
        ],
    }


def sensitivity(plan: Plan, maps: Maps, boat: BoatModel, base: Outcome, rel: float) -> dict:
    """The planned mission's prediction with the current scaled by 1 -+ SIGMAS x rel (the map's own
    uncertainty) and by STRESS (a day of higher discharge than the mapped one)."""
    out = {}
    for k in (1.0 - SIGMAS * rel, 1.0 + SIGMAS * rel, STRESS):
        if k == STRESS:
            name = f"discharge_x{STRESS:g}"
        else:
            name = f"current_x{k:.3f}"
        tr = predict_track(plan.wps, plan.speeds, maps, boat, current_scale=k)
        out[name] = _deltas(score_lines(tr.t, tr.xy, plan.lines), base, tr.duration)
    return out


def plan_mission(
    wps: np.ndarray,
    speeds: np.ndarray | None,
    lines: np.ndarray,
    maps: Maps,
    boat: BoatModel,
    progress=None,  # type: ignore[no-untyped-def]
) -> PlanResult:
    """Predict the mission as given, adjust it to hold ``lines``, predict that, and test its sensitivity."""
    original = outcome(original_plan(wps, speeds, lines), maps, boat)
    if holds(original) and holds(outcome(original.plan, maps, boat, scale=STRESS)):
        planned = original  # nothing to fix: the mission is returned unchanged
    else:
        plan, track = adjust(lines, maps, boat, progress)
        planned = outcome(plan, maps, boat, track)
    when = line_times(planned.track, planned.plan.lines, maps.start)
    rel = relative_sd(planned.plan.lines, maps, when)
    return PlanResult(
        original,
        planned,
        no_headway(planned.plan.lines, maps, boat, when),
        sensitivity(planned.plan, maps, boat, planned, rel),
        rel,
        maps.current.cv_rmse,
        planned is original,
    )


def holds(o: Outcome) -> bool:
    """Whether a predicted mission holds every line: p95 within TOL_M and coverage at least COVERAGE."""
    return o.track.stuck_at is None and all(
        s.p95 <= TOL_M and s.coverage >= COVERAGE for s in o.scores
    )
