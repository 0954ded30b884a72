"""`forcemap run --replan`: the replanner in its own thread beside the acquisition daemon.

The daemon hands it every chunk of MAVLink bytes it reads (``feed``, never blocking: a full queue drops
the chunk, acquisition never waits) and every ``/samples`` row (``sample``, for the maps). The thread
parses the telemetry, reads the mission back from the autopilot (checked against ``--mission`` when
given), follows MISSION_CURRENT, and after each intended line lets the replanner decide; an upload
goes out through ``send`` (the daemon's MAVLink port). Every decision is handed to ``record`` as a
``/plan/replan`` message; the daemon writes it to the log from its own thread.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable

import numpy as np
from forcemap.host.errors import CliError
from forcemap.host.log.messages import Replan
from forcemap.host.vessel.geodesy import LocalFrame
from pymavlink.dialects.v20 import ardupilotmega as M

from .boat_model import BoatModel
from .inflight import Decision, Replanner
from .mission_io import MissionIn, nav_items, survey_lines
from .refit_maps import BoardMaps, RefitMaps
from .upload import Uploader, download, set_current

MODES = {0: "MANUAL", 4: "HOLD", 10: "AUTO", 11: "RTL"}  # ArduPilot Rover's custom_mode
QUEUE_MAX = 2000
RETRY_S = 10.0  # read the mission back again after this long when the autopilot did not answer
WAIT_MAX = (
    1500  # waits (0.2 s each) for a line to end before a decision made ahead of it is dropped
)


def remaining(frame: LocalFrame, wps: np.ndarray | None, speeds: np.ndarray | None) -> list:
    if wps is None or len(wps) == 0:
        return []
    ll = frame.points_to_latlon(wps)
    sp = speeds if speeds is not None else np.full(len(wps), np.nan)
    return [
        [round(float(a), 7), round(float(b), 7), None if not np.isfinite(s) else round(float(s), 2)]
        for (a, b), s in zip(ll, sp, strict=True)
    ]


def to_record(d: Decision, rp: Replanner) -> Replan:
    """The ``/plan/replan`` message of a decision."""
    return Replan(
        t=d.t, line_done=d.line_done, mode=d.mode, uploaded=d.uploaded, reason=d.reason,
        first_seq=d.first_seq,
        old_remaining=remaining(rp.frame, d.old_wps, d.old_speeds),
        new_remaining=remaining(rp.frame, d.new_wps, d.new_speeds),
        old_p95_m=d.old.get("p95_worst_line"), new_p95_m=d.new.get("p95_worst_line"),
        old_coverage=d.old.get("coverage"), new_coverage=d.new.get("coverage"),
        map_age_s=d.map_age_s, map_samples=d.map_samples, current_mean_mps=d.current_mean,
        clipped=d.clipped, clipped_max_m=round(d.clipped_max_m, 2), cpu_s=round(d.cpu_s, 3),
        map_cpu_s=round(d.map_cpu_s, 3), late=d.late, refused=d.refused, turn_end_t=d.turn_end_t,
    )  # fmt: skip


def apply(rp: Replanner, d: Decision, link, now: Callable[[], float]) -> None:  # type: ignore[no-untyped-def]
    """Upload a decision's mission as soon as it is ready, unless the boat has left AUTO or is already
    on the next line: the items up to the line's end (or its overrun) are kept, so the line being flown
    does not change; then set the item. A refused or unanswered upload leaves the autopilot's mission
    as it was. An upload that the boat outran (it reached the next line while the items went out) has
    it go on along that line, never back to the run-in."""
    drain = getattr(link, "drain", None)
    if drain is not None:
        drain()  # the telemetry that arrived while planning: where the boat is now, its mode
    if rp.mode != "AUTO":
        d.reason += "; not sent: the boat left AUTO first"
        rp.uploaded(d, False)
        return
    if not rp.still_in_turn(d):
        d.reason += "; not sent, " + rp.late(d)
        rp.log(f"replan after line {d.line_done + 1}: {rp.late(d)}")
        rp.uploaded(d, False)
        return
    rp.finish(d)  # for the item the boat goes for now
    try:
        Uploader(link, d.items, (1, 1), log=rp.log).run()  # type: ignore[arg-type]
        ok = True
    except (CliError, OSError) as e:
        rp.log(f"replan: upload failed: {e}")
        ok = False
    if ok:
        if drain is not None:
            drain()
        if rp.turn_missed(d):
            d.reason += "; uploaded, but " + rp.late(d).replace(
                "; tried", "; the boat goes on, tried"
            )
            rp.log(f"replan after line {d.line_done + 1}: {rp.late(d)}")
            seq = rp.ahead_on_next(d)
        else:
            seq = rp.resume_seq(d)
        if seq != rp.current:
            set_current(link, seq)
        d.t_sent = now()
    rp.uploaded(d, ok)


class PortLink:
    """pymavlink-style link over bytes the daemon reads (``feed``) and a function that writes."""

    def __init__(self, send: Callable[[bytes], bool], on_message: Callable) -> None:  # type: ignore[type-arg]
        self.send, self.on_message = send, on_message
        self.mav = M.MAVLink(self, srcSystem=255, srcComponent=190)
        self._rx = M.MAVLink(None, srcSystem=255, srcComponent=190)
        self._rx.robust_parsing = True
        self.chunks: queue.Queue[bytes] = queue.Queue(maxsize=QUEUE_MAX)
        self.dropped = 0

    def write(self, buf: bytes) -> None:
        if not self.send(bytes(buf)):
            raise OSError("the MAVLink port is not open")

    def feed(self, data: bytes) -> None:
        try:
            self.chunks.put_nowait(data)
        except queue.Full:
            self.dropped += 1

    def pump(self, timeout: float) -> list:
        """Messages parsed from the next chunk (waiting up to ``timeout``), each passed to on_message."""
        try:
            data = self.chunks.get(timeout=max(timeout, 0.0))
        except queue.Empty:
            return []
        msgs = [m for m in (self._rx.parse_buffer(data) or []) if m.get_type() != "BAD_DATA"]
        for m in msgs:
            self.on_message(m)
        return msgs

    def drain(self) -> None:
        """Parse every chunk waiting (telemetry is passed on; nothing is kept)."""
        while not self.chunks.empty():
            self.pump(0.0)

    def recv_match(self, type, blocking=True, timeout=None):  # type: ignore[no-untyped-def]  # noqa: A002
        end = time.monotonic() + (timeout or 0.0)
        while True:
            for m in self.pump(end - time.monotonic()):
                if m.get_type() in type:
                    return m
            if time.monotonic() >= end:
                return None


class ReplanService(threading.Thread):
    """Reads the mission back, follows the autopilot, decides after each line, uploads, records."""

    def __init__(
        self,
        mission: MissionIn | None,
        boat: BoatModel,
        send: Callable[[bytes], bool],
        record: Callable[[Replan], object],
        log: Callable[[str], object],
        bound_m: float = 30.0,
        stop: threading.Event | None = None,
        board=None,  # type: ignore[no-untyped-def]  # the live map's MapBoard (--live), if any
        terms: list[str] | None = None,  # the refit's terms (--replan-terms; default the baseline)
    ) -> None:
        super().__init__(name="replan", daemon=True)
        self.terms = terms
        self.mission, self.boat, self.record, self.log = mission, boat, record, log
        self.bound_m, self.board = bound_m, board
        self.stop_event = stop or threading.Event()
        self.link = PortLink(send, self._telemetry)
        self.rp: Replanner | None = None
        self.maps: RefitMaps | None = None
        self._pending: list[Decision] = []
        self._early: list[dict] = []
        self.last_t = 0.0  # the newest sample's time: the daemon's clock, for the map's age
        # the live view's `/map/mission` (--live): the intended lines and the mission the autopilot holds
        self.on_plan: Callable[[np.ndarray, np.ndarray], object] | None = None

    # called from the daemon's thread: quick, never blocking
    def feed(self, data: bytes) -> None:
        self.link.feed(data)

    def sample(self, row: dict) -> None:
        self.last_t = row.get("t") or self.last_t
        if self.board is not None:
            return  # the live map process has them
        if self.maps is not None:
            self.maps.add(row)
        elif len(self._early) < 100_000:
            self._early.append(row)

    def _telemetry(self, m) -> None:  # type: ignore[no-untyped-def]
        rp, kind = self.rp, m.get_type()
        if rp is None:
            return
        if kind == "HEARTBEAT" and m.get_srcComponent() == 1:
            rp.heartbeat(MODES.get(int(m.custom_mode), f"mode {m.custom_mode}"))
        elif kind == "GLOBAL_POSITION_INT" and m.lat:
            d = rp.position(m.lat * 1e-7, m.lon * 1e-7, self.last_t)
            if d is not None:
                self._pending.append(d)
        elif kind == "MISSION_CURRENT":
            d = rp.mission_current(int(m.seq), self.last_t)
            if d is not None:
                self._pending.append(d)

    def _start(self) -> bool:
        """Read the autopilot's mission back and set the replanner up; False to try again later."""
        try:
            items = download(self.link)
        except (CliError, OSError) as e:
            self.log(f"replan: cannot read the mission back yet ({e}); trying again")
            return False
        nav = nav_items(items)[0]
        if self.mission is not None:
            if not same_waypoints(nav, self.mission.latlon):
                self.log(
                    "replan: the autopilot holds another mission than --mission: replanning off"
                )
                self.stop_event.set()
                return False
            lines = self.mission.lines_latlon
        else:
            frame = LocalFrame(float(nav[0, 0]), float(nav[0, 1]))
            lines = frame.points_to_latlon(survey_lines(frame.points_to_local(nav)))
        latlon = np.array([[i.lat, i.lon] for i in items[1:]])
        frame = LocalFrame(float(latlon[:, 0].mean()), float(latlon[:, 1].mean()))
        xy = frame.points_to_local(latlon)
        lo, hi = xy.min(axis=0) - 120.0, xy.max(axis=0) + 120.0
        provider: BoardMaps | RefitMaps
        if self.board is not None:
            provider = BoardMaps(self.board, frame.lat0, frame.lon0)
        else:
            self.maps = provider = RefitMaps(
                frame.lat0, frame.lon0, (lo[0], hi[0], lo[1], hi[1]), self.terms
            )
            for row in self._early:
                self.maps.add(row)
        self._early = []
        self.lines_latlon = np.asarray(lines, dtype=float)
        self.rp = Replanner(items, lines, frame, self.boat, provider, bound_m=self.bound_m,
                            log=self.log)  # fmt: skip
        self.log(f"replan: following the autopilot's mission ({len(items) - 1} items, "
                 f"{len(lines)} intended lines)")  # fmt: skip
        self._show_plan()
        return True

    def _show_plan(self) -> None:
        """Hand the intended lines and the autopilot's waypoints to the live view, if there is one."""
        if self.on_plan is not None and self.rp is not None:
            self.on_plan(self.lines_latlon, self.rp.frame.points_to_latlon(self.rp.xy))

    def run(self) -> None:
        next_try = 0.0
        while not self.stop_event.is_set():
            if self.rp is None:
                if time.monotonic() >= next_try and not self._start():
                    next_try = time.monotonic() + RETRY_S
                self.link.pump(0.2)
                continue
            self.link.pump(0.2)
            while self._pending:
                d = self._pending.pop(0)
                try:
                    self.rp.note_latency(self.last_t - d.t)
                    if d.items is not None:
                        apply(self.rp, d, self.link, time.time)
                    self.record(to_record(d, self.rp))
                    if d.uploaded:
                        self._show_plan()
                except Exception as e:  # a bug in planning must never reach acquisition
                    self.log(f"replan: decision failed ({e!r}); mission kept")


def same_waypoints(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two lists of waypoints (lat/lon) agree to 2.5e-7 degrees (MISSION_ITEM_INT keeps 1e-7)."""
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= 2.5e-7))
