"""In-flight replanning: after each intended line, plan the rest of the mission on the latest maps and
decide whether the autopilot should fly that instead (issue 22; docs/PLAN.md, "In flight").

The replanner follows the autopilot through its telemetry (HEARTBEAT mode, MISSION_CURRENT, position)
and knows the mission the autopilot holds. When MISSION_CURRENT moves past the last waypoint of an
intended line, it takes the latest maps (a ``MapProvider``), predicts the remaining mission as the
autopilot holds it and as `host/plan` would lay it out from here (run-ins, overruns, turn points moved
against the drift, leg speeds, lines in the order and directions given), and returns a ``Decision``:
the new mission (the items already flown and the waypoint the boat is going for unchanged, the rest
replaced) or the reason not to. The caller uploads it and says how that went (``uploaded``).

What it never does: decide mid-line (only when a line has ended and the next has not started), decide
in a mode other than AUTO, move a waypoint more than ``bound_m`` across its line or outside the
mission's area plus ``margin_m`` (clipped, counted in the decision), or use a map with values no river
or wind has (NaN, a current over MAX_CURRENT_MPS, a wind over MAX_WIND_MPS).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame

from .adjust import adjust
from .boat_model import BoatModel
from .maps import Field, Maps
from .metrics import score_lines, summary
from .mission_io import mission_items, nav_items
from .predict import predict_track

BOUND_M = 30.0  # largest move of a waypoint across its intended line
MARGIN_M = 60.0  # the mission's area (its waypoints and lines) grown by this much
MAX_CURRENT_MPS = 8.0  # faster than any river a survey boat works in
MAX_WIND_MPS = 40.0
MIN_GAIN_M = 0.3  # upload when the worst remaining line's predicted p95 improves by this much ...
MIN_COVERAGE_GAIN = 0.01  # ... or the remaining lines' predicted coverage by this share


@dataclass
class MapSnapshot:
    """The latest maps, the time of the newest sample they were fitted on, and how many samples."""

    maps: Maps
    t_data: float
    samples: int = 0


MapProvider = Callable[[], "MapSnapshot | None"]


@dataclass
class Decision:
    """One decision after an intended line; ``items`` (the whole new mission, home first) if worth it."""

    t: float
    line_done: int
    mode: str
    reason: str
    items: list | None = None
    first_seq: int | None = None
    set_current: int | None = None
    first_nav: int | None = None  # seq of the first new waypoint
    line_seqs: list[tuple[int, int]] = field(default_factory=list)
    old: dict = field(default_factory=dict)  # predicted summary of the remaining lines
    new: dict = field(default_factory=dict)
    old_wps: np.ndarray | None = None  # remaining waypoints (local m) and speeds, before and after
    old_speeds: np.ndarray | None = None
    new_wps: np.ndarray | None = None
    new_speeds: np.ndarray | None = None
    map_age_s: float | None = None
    map_samples: int | None = None
    current_mean: float | None = None  # mapped current speed, mean along all intended lines
    clipped: int = 0
    clipped_max_m: float = 0.0
    cpu_s: float = 0.0  # the decision's CPU time, without the map's
    map_cpu_s: float = 0.0  # getting the maps (a refit, when the provider refits on demand)
    uploaded: bool = False
    t_sent: float | None = None  # when the new mission was accepted (the caller's time)


def map_problem(maps: Maps, area: tuple[float, float, float, float]) -> str | None:
    """Why a map cannot be trusted over ``area`` (x0, x1, y0, y1), or None."""
    for name, f, limit in (
        ("current", maps.current, MAX_CURRENT_MPS),
        ("wind", maps.wind, MAX_WIND_MPS),
    ):
        e, n = _in_area(f, area)
        if not (np.all(np.isfinite(e)) and np.all(np.isfinite(n))):
            return f"the {name} map has values that are not numbers"
        top = float(np.max(np.hypot(e, n))) if e.size else 0.0
        if top > limit:
            return f"the {name} map reaches {top:.1f} m/s (more than {limit:g} m/s)"
    return None


def _in_area(f: Field, area: tuple[float, float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    ny, nx = f.east.shape
    gx = f.x0 + f.step * np.arange(nx)
    gy = f.y0 + f.step * np.arange(ny)
    cx = (gx >= area[0] - f.step) & (gx <= area[1] + f.step)
    cy = (gy >= area[2] - f.step) & (gy <= area[3] + f.step)
    if not cx.any() or not cy.any():  # a coarse grid (one cell over everything): all of it
        return f.east, f.north
    return f.east[np.ix_(cy, cx)], f.north[np.ix_(cy, cx)]


def owners(line_wps: list[tuple[int, int]], n: int) -> np.ndarray:
    """For each waypoint of a laid-out plan, the line it belongs to (run-in, on it, overrun); -1: none."""
    out = np.full(n, -1)
    for j, (a, b) in enumerate(line_wps):
        out[max(a - 1, 0) : min(b + 2, n)] = j
    return out


def clip(
    wps: np.ndarray, own: np.ndarray, lines: np.ndarray, bound_m: float, area: tuple
) -> tuple[np.ndarray, int, float]:
    """Waypoints moved back within ``bound_m`` across their line and into ``area``; how many moved, and
    the largest move (m)."""
    out = wps.copy()
    for k, j in enumerate(own):
        if j < 0:
            continue
        a, b = lines[j]
        u = (b - a) / np.hypot(*(b - a))
        nrm = np.array([u[1], -u[0]])
        off = float((out[k] - a) @ nrm)
        if abs(off) > bound_m:
            out[k] -= (off - np.sign(off) * bound_m) * nrm
    out[:, 0] = np.clip(out[:, 0], area[0], area[1])
    out[:, 1] = np.clip(out[:, 1], area[2], area[3])
    moved = np.hypot(*(out - wps).T)
    return out, int(np.sum(moved > 0.01)), float(moved.max()) if len(moved) else 0.0


class Replanner:
    """The mission the autopilot holds, where it is in it, and the decision after each line."""

    def __init__(
        self,
        items: list,
        lines_latlon: np.ndarray,
        frame: LocalFrame,
        boat: BoatModel,
        maps: MapProvider,
        bound_m: float = BOUND_M,
        margin_m: float = MARGIN_M,
        log: Callable[[str], object] | None = None,
    ) -> None:
        self.frame, self.boat, self.maps = frame, boat, maps
        self.bound_m = bound_m
        self.log = log or (lambda s: None)
        self.lines = frame.points_to_local(np.asarray(lines_latlon, dtype=float))
        # points every ~10 m along every intended line: where the map's mean current is reported
        self.along = np.concatenate(
            [a + np.linspace(0, 1, max(int(np.hypot(*(b - a)) / 10), 2))[:, None] * (b - a)
             for a, b in self.lines]
        )  # fmt: skip
        self.set_items(items, None)
        pts = np.vstack([self.xy, self.lines.reshape(-1, 2)])
        lo, hi = pts.min(axis=0) - margin_m, pts.max(axis=0) + margin_m
        self.area = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
        self.mode = "AUTO"
        self.current: int | None = None
        self.pos: np.ndarray | None = None
        self.done = -1  # the last intended line finished

    def set_items(self, items: list, line_seqs: list[tuple[int, int]] | None) -> None:
        """The mission the autopilot now holds (home first); where each line starts and ends in it."""
        self.items = list(items)
        latlon, self.speeds, self.seqs = nav_items(self.items)
        self.xy = self.frame.points_to_local(latlon)
        if line_seqs is None:  # the original: each line's ends are its nearest waypoints
            line_seqs = []
            for a, b in self.lines:
                ia = int(np.argmin(np.hypot(*(self.xy - a).T)))
                ib = int(np.argmin(np.hypot(*(self.xy - b).T)))
                line_seqs.append((int(self.seqs[ia]), int(self.seqs[ib])))
        self.line_seqs = list(line_seqs)

    # ---- telemetry ---------------------------------------------------------------------------------
    def heartbeat(self, mode: str) -> None:
        if mode != self.mode:
            self.log(f"replan: mode {mode}" + ("" if mode == "AUTO" else ", not replanning"))
        self.mode = mode

    def position(self, lat: float, lon: float) -> None:
        self.pos = self.frame.points_to_local(np.array([lat, lon]))

    def mission_current(self, seq: int, t: float) -> Decision | None:
        """A MISSION_CURRENT; the decision when it says an intended line has just ended."""
        self.current = seq
        ended = self.done
        while ended + 1 < len(self.lines) and seq > self.line_seqs[ended + 1][1]:
            ended += 1
        if ended == self.done:
            return None
        self.done = ended
        if ended + 1 >= len(self.lines) or self.pos is None:
            return None
        return self.decide(ended, t)

    # ---- the decision ------------------------------------------------------------------------------
    def decide(self, i: int, t: float) -> Decision:
        """Plan the lines after line ``i`` from here; a Decision with the new mission if it is worth it."""
        cpu0 = time.process_time()
        d = Decision(t, i, self.mode, "")
        d.reason = self._plan(d, i, t)
        d.cpu_s = time.process_time() - cpu0 - d.map_cpu_s
        self.log(f"replan after line {i + 1}: {d.reason}")
        return d

    def _plan(self, d: Decision, i: int, t: float) -> str:
        if self.mode != "AUTO":
            return f"mode {self.mode}: no replanning until AUTO"
        c, start_next = int(self.current or 0), self.line_seqs[i + 1][0]
        if c > start_next:
            return "too late: the boat is already on the next line"
        cpu0 = time.process_time()
        snap = self.maps()
        d.map_cpu_s = time.process_time() - cpu0
        if snap is None:
            return "no map yet"
        d.map_age_s, d.map_samples = round(t - snap.t_data, 1), snap.samples
        bad = map_problem(snap.maps, self.area)
        if bad:
            return f"map rejected, mission kept: {bad}"
        maps, rest = snap.maps, self.lines[i + 1 :]
        e, n, _ = maps.current.sample(self.along)
        d.current_mean = round(float(np.mean(np.hypot(e, n))), 3)
        ahead = self.seqs >= c
        old_w = np.vstack([self.pos, self.xy[ahead]])
        old_s = np.r_[np.nan, self.speeds[ahead]]
        d.old_wps, d.old_speeds = old_w[1:], old_s[1:]
        d.old = self._predict(old_w, old_s, rest, maps)
        keep = c < start_next  # the turn point the boat is going for stays (an overrun)
        k_c = int(np.searchsorted(self.seqs, c))
        begin = self.xy[k_c] if keep else self.pos
        plan, _ = adjust(rest, maps, self.boat, start=begin, reorder=False)
        wps, speeds = plan.wps[1:], plan.speeds[1:]
        own = owners([(a - 1, b - 1) for a, b in plan.line_wps], len(wps))
        wps, d.clipped, d.clipped_max_m = clip(wps, own, rest, self.bound_m, self.area)
        if d.clipped:
            self.log(
                f"replan: {d.clipped} waypoint(s) moved back within the bounds "
                f"(up to {d.clipped_max_m:.1f} m)"
            )
        head = [self.pos, self.xy[k_c]] if keep else [self.pos]
        new_w = np.vstack([*head, wps])
        new_s = np.r_[[np.nan] * len(head), speeds]
        d.new_wps, d.new_speeds = wps, speeds
        d.new = self._predict(new_w, new_s, rest, maps)
        gain_p95 = d.old["p95_worst_line"] - d.new["p95_worst_line"]
        gain_cov = d.new["coverage"] - d.old["coverage"]
        if d.new["stuck"] or not (
            (gain_p95 >= MIN_GAIN_M and gain_cov >= -0.005)
            or (gain_cov >= MIN_COVERAGE_GAIN and gain_p95 >= -0.1)
        ):
            return (
                f"kept: predicted gain too small (p95 {d.old['p95_worst_line']:.2f} -> "
                f"{d.new['p95_worst_line']:.2f} m, coverage {d.old['coverage']:.1%} -> "
                f"{d.new['coverage']:.1%})"
            )
        d.first_seq = c + 1 if keep else c
        self._new_items(d, wps, speeds, plan.line_wps, c if keep else None)
        return (
            f"upload: predicted p95 {d.old['p95_worst_line']:.2f} -> {d.new['p95_worst_line']:.2f} m, "
            f"coverage {d.old['coverage']:.1%} -> {d.new['coverage']:.1%}"
        )

    def _predict(self, wps: np.ndarray, speeds: np.ndarray, lines: np.ndarray, maps: Maps) -> dict:
        tr = predict_track(wps, speeds, maps, self.boat)
        out = summary(score_lines(tr.t, tr.xy, lines))
        out = {k: round(float(v), 3) for k, v in out.items()}
        return {**out, "duration_s": round(tr.duration, 1), "stuck": tr.stuck_at is not None}

    def _new_items(self, d: Decision, wps, speeds, line_wps, kept: int | None) -> None:  # type: ignore[no-untyped-def]
        latlon = self.frame.points_to_latlon(wps)
        part = mission_items(latlon, speeds, self.boat.cruise_speed)
        d.items = self.items[: d.first_seq] + part
        _, _, seqs = nav_items(d.items)
        new_seqs = seqs[seqs >= d.first_seq]  # type: ignore[operator]
        d.first_nav = int(new_seqs[0])
        d.set_current = kept if kept is not None else d.first_nav
        d.line_seqs = [(-1, -1)] * (d.line_done + 1) + [
            (int(new_seqs[a - 1]), int(new_seqs[b - 1])) for a, b in line_wps
        ]

    def still_in_turn(self, d: Decision) -> bool:
        """Whether the boat, in AUTO, has not yet started the line after the one ``d`` followed."""
        start_next = self.line_seqs[d.line_done + 1][0]
        return self.mode == "AUTO" and int(self.current or 0) <= start_next

    def resume_seq(self, d: Decision) -> int:
        """The item to go for once ``d`` is accepted: the kept turn point, or the first new waypoint
        if the boat has passed it while the upload went on."""
        assert d.set_current is not None and d.first_nav is not None
        return d.set_current if int(self.current or 0) <= d.set_current else d.first_nav

    def uploaded(self, d: Decision, ok: bool) -> None:
        """How the upload of ``d`` went: the autopilot's mission is the new one only if it was accepted."""
        d.uploaded = ok
        if ok and d.items is not None:
            self.set_items(d.items, d.line_seqs)
        elif d.items is not None:
            d.reason += (
                "; upload failed: the autopilot keeps its mission, retry after the next line"
            )
            self.log(f"replan after line {d.line_done + 1}: upload failed, mission kept")
