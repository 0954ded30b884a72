"""In-flight replanning: after each intended line, plan the rest of the mission on the latest maps and
decide whether the autopilot should fly that instead (issue 22; docs/PLAN.md, "In flight").

The replanner follows the autopilot through its telemetry (HEARTBEAT mode, MISSION_CURRENT, position)
and knows the mission the autopilot holds. A little before the boat reaches the end of an intended line
(its position projected on the line; host/plan/line_progress.py), or when the line ends, it takes the
latest maps (a ``MapProvider``), predicts the remaining mission as the
autopilot holds it and as `host/plan` would lay it out from here (run-ins, overruns, turn points moved
against the drift, leg speeds, lines in the order and directions given), and returns a ``Decision``:
the new mission (the items already flown and the waypoint the boat is going for unchanged, the rest
replaced, its DO_ items kept: host/plan/splice.py) or the reason not to. The caller uploads it as soon
as it is ready (``apply`` in service.py: the line being flown is kept up to its end) and says how that
went (``uploaded``); a decision that misses its turn says so with its timings, and the next turn gets
a new one.

What it never does: change the line being flown, upload once the boat is on the next line, decide
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
from forcemap.host.vessel.waypoints import NAV_WAYPOINT

from . import line_progress as lp
from .adjust import adjust
from .boat_model import BoatModel
from .bounds import BOUND_M, MARGIN_M, clip, map_problem, owners
from .line_progress import match_lines
from .maps import Maps
from .metrics import score_lines, summary
from .mission_io import nav_items, survey_legs
from .predict import predict_track
from .splice import splice

MIN_GAIN_M = 0.3  # upload when the worst remaining line's predicted p95 improves by this much ...
MIN_COVERAGE_GAIN = 0.01  # ... or the remaining lines' predicted coverage by this share
LEAD_S = 30.0  # decide this long (the data's clock) before a line ends, at least ...
LEAD_MAX_S = 90.0  # ... and at most, however slow the last decisions were


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
    keep_seq: int | None = None  # the last item of the held mission kept as it is
    plan_lines: list[tuple[int, int]] = field(default_factory=list)  # in new_wps
    late: bool = False  # it missed its turn (the boat was on the next line first)
    turn_end_t: float | None = None  # when that turn ended (the data's clock)
    refused: bool = False  # the autopilot refused the upload, or did not answer it


class Replanner:
    """The mission the autopilot holds, where the boat is on its lines, and the decision for each turn.

    A decision is taken ``lead_s`` (the data's clock) before the boat reaches the end of a line, or when
    the line ends if that comes first, and must be uploaded before the turn after it is over: before
    the boat is on the next line (host/plan/line_progress.py).
    """

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
        lead_s: float = LEAD_S,
    ) -> None:
        self.frame, self.boat, self.maps = frame, boat, maps
        self.bound_m, self.lead_s = bound_m, lead_s
        self.log = log or (lambda s: None)
        self.lines = frame.points_to_local(np.asarray(lines_latlon, dtype=float))
        survey = survey_legs(self.lines)
        if not survey.all():  # short connectors between survey lines, given as lines: turns
            self.log(f"replan: {int((~survey).sum())} of the {len(survey)} intended lines are short "
                     "connectors between the survey lines: flown as turns")  # fmt: skip
            self.lines = self.lines[survey]
        self.set_items(items, None)
        # points every ~10 m along every intended line: where the map's mean current is reported
        self.along = np.concatenate(
            [a + np.linspace(0, 1, max(int(np.hypot(*(b - a)) / 10), 2))[:, None] * (b - a)
             for a, b in self.lines]
        )  # fmt: skip
        pts = np.vstack([self.xy, self.lines.reshape(-1, 2)])
        lo, hi = pts.min(axis=0) - margin_m, pts.max(axis=0) + margin_m
        self.area = (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))
        self.mode = "AUTO"
        self.current: int | None = None
        self.pos: np.ndarray | None = None
        self.t = 0.0
        self.done = -1  # the last intended line decided for
        self.on_line = -1  # the last intended line the boat has been seen flying
        self.turn_end_t: dict[int, float] = {}  # line -> when the turn after it ended
        self.warmed = False

    def set_items(self, items: list, line_seqs: list[tuple[int, int]] | None) -> None:
        """The mission the autopilot now holds (home first); where each line starts and ends in it."""
        self.items = list(items)
        latlon, self.speeds, self.seqs = nav_items(self.items)
        self.xy = self.frame.points_to_local(latlon)
        if line_seqs is None:  # the original: lines oriented and ordered as the mission flies them
            self.lines, line_seqs = match_lines(self.lines, self.xy, self.seqs)
        self.line_seqs = list(line_seqs)

    # ---- telemetry ---------------------------------------------------------------------------------
    def heartbeat(self, mode: str) -> None:
        if mode != self.mode:
            self.log(f"replan: mode {mode}" + ("" if mode == "AUTO" else ", not replanning"))
        self.mode = mode

    def position(self, lat: float, lon: float, t: float | None = None) -> Decision | None:
        """A position; the decision when it brings the end of a line within reach."""
        self.pos = self.frame.points_to_local(np.array([lat, lon]))
        if t is None:
            return None
        self.t = t
        return self.update()

    def mission_current(self, seq: int, t: float) -> Decision | None:
        """A MISSION_CURRENT; the decision when the line has ended or is about to."""
        self.current, self.t = seq, t
        return self.update()

    def _watch(self) -> None:
        while self.on_line + 1 < len(self.lines) and lp.turn_over(
            self.pos, self.current, self.lines[self.on_line + 1], self.line_seqs[self.on_line + 1]
        ):
            self.on_line += 1
            if self.on_line > 0:
                self.turn_end_t.setdefault(self.on_line - 1, self.t)

    def update(self) -> Decision | None:
        """The decision for the turn after the line being flown, once it is near or over."""
        self._watch()
        i = self.done + 1
        if i + 1 >= len(self.lines) or self.pos is None:
            return None
        args = (self.pos, self.current, self.lines[i], self.line_seqs[i])
        left = lp.to_go(*args)
        if not self.warmed and left < 0.5 * lp.along_across(self.pos, *self.lines[i])[2]:
            self.warmed = True  # a first map half-way along the first line: the first fit's cost
            self.maps()  # (imports, caches) is not paid by the first decision

        if not (lp.line_ended(*args) or left <= self.boat.cruise_speed * self.lead_s):
            return None
        self.done = i
        return self.decide(i, self.t)

    def line_over(self, d: Decision) -> bool:
        """Whether the line ``d`` is for has ended (the turn has begun)."""
        i = d.line_done
        return lp.line_ended(self.pos, self.current, self.lines[i], self.line_seqs[i])

    def turn_missed(self, d: Decision) -> bool:
        """Whether the boat is already on the line after the turn ``d`` was for."""
        self._watch()
        return self.on_line > d.line_done

    def late(self, d: Decision) -> str:
        """Why ``d`` missed its turn, with its timings."""
        d.late = True
        d.turn_end_t = self.turn_end_t.get(d.line_done, self.t)
        return (
            f"late: decided at t={d.t:.1f} s, the turn ended at t={d.turn_end_t:.1f} s, "
            f"CPU {d.cpu_s + d.map_cpu_s:.2f} s; tried again at the next turn"
        )

    def note_latency(self, seconds: float) -> None:
        """How long (the data's clock) a decision took to be ready: the next ones are made 1.5 times
        the longer of the last two that early (a loaded machine, a fast simulation)."""
        self.latencies = [*getattr(self, "latencies", [])[-1:], float(seconds)]
        self.lead_s = float(np.clip(1.5 * max(self.latencies), LEAD_S, LEAD_MAX_S))

    # ---- the decision ------------------------------------------------------------------------------
    def decide(self, i: int, t: float) -> Decision:
        """Plan the lines after line ``i`` from its end; a Decision with the new mission if worth it."""
        cpu0 = time.process_time()
        d = Decision(t, i, self.mode, "")
        d.reason = self._plan(d, i, t)
        d.cpu_s = time.process_time() - cpu0 - d.map_cpu_s
        self.log(f"replan after line {i + 1}: {d.reason}")
        return d

    def _keep_seq(self, i: int) -> int:
        """The last item kept: line ``i``'s end, or an overrun point straight after it."""
        end = self.line_seqs[i][1]
        over = self._overrun(i)
        return over if over is not None and over < self.line_seqs[i + 1][0] else int(end)

    def _overrun(self, i: int) -> int | None:
        """The waypoint right after line ``i``'s end if it carries straight on (within 15 degrees)."""
        k = int(np.searchsorted(self.seqs, self.line_seqs[i][1]))
        if k + 1 < len(self.seqs):
            along, across, length = lp.along_across(self.xy[k + 1], *self.lines[i])
            if along > length and abs(across) < 0.27 * (along - length):
                return int(self.seqs[k + 1])
        return None

    def _plan(self, d: Decision, i: int, t: float) -> str:
        if self.mode != "AUTO":
            return f"mode {self.mode}: no replanning until AUTO"
        if self.turn_missed(d):
            return self.late(d)
        c = int(self.current or 0)
        keep = self._keep_seq(i)
        if c <= keep:
            d.keep_seq, begin = keep, self.xy[int(np.searchsorted(self.seqs, keep))]
        else:
            d.keep_seq, begin = c - 1, self.pos
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
        e, n, _ = maps.current.sample(self.along, t)
        d.current_mean = round(float(np.mean(np.hypot(e, n))), 3)
        ahead = self.seqs > d.keep_seq
        d.old_wps, d.old_speeds = self.xy[ahead], self.speeds[ahead]
        d.old = self._predict(
            np.vstack([begin, d.old_wps]), np.r_[np.nan, d.old_speeds], rest, maps, t
        )
        # from now, on the data's clock: a current that changes in time is read when the boat is there
        plan, _ = adjust(rest, maps, self.boat, start=begin, reorder=False, t_start=t)
        wps, speeds = plan.wps[1:], plan.speeds[1:]
        d.plan_lines = [(a - 1, b - 1) for a, b in plan.line_wps]
        wps, d.clipped, d.clipped_max_m = clip(
            wps, owners(d.plan_lines, len(wps)), rest, self.bound_m, self.area
        )
        if d.clipped:
            self.log(
                f"replan: {d.clipped} waypoint(s) moved back within the bounds "
                f"(up to {d.clipped_max_m:.1f} m)"
            )
        d.new_wps, d.new_speeds = wps, speeds
        d.new = self._predict(np.vstack([begin, wps]), np.r_[np.nan, speeds], rest, maps, t)
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
        self.finish(d)
        return (
            f"upload: predicted p95 {d.old['p95_worst_line']:.2f} -> {d.new['p95_worst_line']:.2f} m, "
            f"coverage {d.old['coverage']:.1%} -> {d.new['coverage']:.1%}"
        )

    def _predict(
        self, wps: np.ndarray, speeds: np.ndarray, lines: np.ndarray, maps: Maps, t: float
    ) -> dict:
        tr = predict_track(wps, speeds, maps, self.boat, t_start=t)
        out = summary(score_lines(tr.t, tr.xy, lines))
        out = {k: round(float(v), 3) for k, v in out.items()}
        return {**out, "duration_s": round(tr.duration, 1), "stuck": tr.stuck_at is not None}

    def finish(self, d: Decision) -> None:
        """The whole new mission of ``d`` for where the boat is now: the items up to the kept one (or
        up to the one the boat goes for, if it has passed it), then the plan, the other items kept."""
        assert d.new_wps is not None and d.new_speeds is not None and d.keep_seq is not None
        c = int(self.current or 0)
        d.first_seq = d.keep_seq + 1 if c <= d.keep_seq else c
        items, new_seqs, line_seqs = splice(
            self.items, d.first_seq, self.line_seqs, d.line_done + 1,
            self.frame.points_to_latlon(d.new_wps), d.new_speeds, d.plan_lines,
            self.boat.cruise_speed, self._overrun(len(self.lines) - 1),
        )  # fmt: skip
        d.items, d.first_nav = items, new_seqs[0]
        d.set_current = c if c <= d.keep_seq else d.first_nav
        d.line_seqs = self.line_seqs[: d.line_done + 1] + line_seqs

    def still_in_turn(self, d: Decision) -> bool:
        """Whether the boat, in AUTO, has not yet started the line after the one ``d`` followed."""
        return self.mode == "AUTO" and not self.turn_missed(d)

    def ahead_on_next(self, d: Decision) -> int:
        """In ``d``'s mission, the waypoint of the next line at least ON_NEXT_M ahead of the boat."""
        assert d.items is not None and self.pos is not None
        first, last = d.line_seqs[d.line_done + 1]
        a, b = self.lines[d.line_done + 1]
        here = lp.along_across(self.pos, a, b)[0]
        geo = self.frame
        for seq in range(first, last + 1):
            it = d.items[seq]
            if it.command == NAV_WAYPOINT:
                p = geo.points_to_local(np.array([it.lat, it.lon]))
                if lp.along_across(p, a, b)[0] > here + lp.ON_NEXT_M:
                    return seq
        return last

    def resume_seq(self, d: Decision) -> int:
        """The item to go for once ``d`` is accepted: the one the boat goes for, if it is among the items
        kept (the line it is flying), else the first new waypoint (it went on into the turn)."""
        assert d.first_nav is not None and d.keep_seq is not None
        c = int(self.current or 0)
        return c if d.first_seq == d.keep_seq + 1 and c <= d.keep_seq else d.first_nav

    def uploaded(self, d: Decision, ok: bool) -> None:
        """How the upload of ``d`` went: the autopilot's mission is the new one only if it was accepted."""
        d.uploaded = ok
        if ok and d.items is not None:
            self.set_items(d.items, d.line_seqs)
        elif d.items is not None and not d.late and "not sent" not in d.reason:
            d.refused = True
            d.reason += (
                "; upload failed: the autopilot keeps its mission, retry after the next line"
            )
            self.log(f"replan after line {d.line_done + 1}: upload failed, mission kept")
