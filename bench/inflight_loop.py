"""In-flight replanning judged against the simulator's truth: the first survey of an unmapped river.

The simulator's bytes go through the daemon's pipeline (measured current and wind, never the truth);
the replanner (host/plan/inflight.py) follows the autopilot's MAVLink telemetry, refits the maps on
the samples so far after each line (host/plan/refit_maps.py), and uploads with the ground side of the
mission protocol (host/plan/upload.py) over an offline link: what it sends goes into the simulated
autopilot, and waiting for an answer advances the simulation's virtual time (the boat flies on).
A decision is applied ``LATENCY_S`` of virtual time after it was asked for (the time to plan on the
boat's computer). The flown track is scored on the intended lines with the true track.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.fuse import calibration
from forcemap.host.fuse.pipeline import Pipeline
from forcemap.host.log.messages import as_json
from forcemap.host.plan.boat_model import BoatModel
from forcemap.host.plan.inflight import Decision, Replanner
from forcemap.host.plan.metrics import score_lines, summary
from forcemap.host.plan.mission_io import read_mission
from forcemap.host.plan.refit_maps import RefitMaps
from forcemap.host.plan.service import apply
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel.boat import BoatParams
from forcemap.host.vessel.control import Gains
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.sim_devices import modes as md
from forcemap.sim_devices.engine import DT, Simulation
from forcemap.sim_devices.jetyak import JETYAK, ROVER_GAINS
from pymavlink.dialects.v20 import ardupilotmega as M

LATENCY_S = 2.0
JUDGED_FROM = 2  # lines before this one (0-based) are not judged: no map could have helped them


class OfflineLink:
    """A pymavlink-style connection to an offline Simulation's autopilot (``mav.send``, ``recv_match``)."""

    def __init__(self, sim: Simulation, on_message) -> None:  # type: ignore[no-untyped-def]
        self.sim, self.on_message = sim, on_message
        self.mav = M.MAVLink(self, srcSystem=255, srcComponent=190)
        self._rx = M.MAVLink(None, srcSystem=255, srcComponent=190)
        self._rx.robust_parsing = True
        self.inbox: deque = deque()
        self.listening = False

    def write(self, buf: bytes) -> None:
        self.sim.uplink(bytes(buf))

    def feed(self, data: bytes) -> None:
        for m in self._rx.parse_buffer(data) or []:
            if m.get_type() == "BAD_DATA":
                continue
            self.on_message(m)
            if self.listening:
                self.inbox.append(m)

    def recv_match(self, type, blocking=True, timeout=None):  # type: ignore[no-untyped-def]  # noqa: A002
        end = self.sim.t + (timeout or 0.0)
        self.listening = True
        try:
            while True:
                while self.inbox:
                    m = self.inbox.popleft()
                    if m.get_type() in type:
                        return m
                if self.sim.t >= end - 1e-9 or self.sim.t >= self.sim.duration:
                    return None
                self.sim.advance(self.sim.t + DT)
        finally:
            self.listening = False


def mission(scenario: str) -> ms.Mission:
    """The lawnmower once through, with its legs as the intended lines."""
    m = ms.load("lawnmower", sc.load(scenario))
    return ms.Mission(
        m.name, m.description, m.waypoints, False, None, m.waypoints.reshape(-1, 2, 2)
    )


def perturbed(draw: int) -> tuple[BoatParams, Gains, dict]:
    """A boat unlike the planner's: drag, thrust, turning lever arm and steering/speed gains each x a
    factor in [0.8, 1.2] (seeded draw)."""
    rng = np.random.default_rng(1000 + draw)
    f = {k: float(rng.uniform(0.8, 1.2)) for k in ("drag", "thrust", "turn", "gains")}
    p, g = JETYAK, ROVER_GAINS
    from dataclasses import replace

    p = replace(
        p, x_u=p.x_u * f["drag"], x_uu=p.x_uu * f["drag"], thrust_max=p.thrust_max * f["thrust"],
        jet_arm=p.jet_arm * f["turn"],
    )  # fmt: skip
    g = replace(
        g, steer_kp=g.steer_kp * f["gains"], steer_kd=g.steer_kd * f["gains"],
        speed_kp=g.speed_kp * f["gains"],
    )  # fmt: skip
    return p, g, f


@dataclass
class Run:
    lines: list  # per intended line: LineScore as JSON
    judged: dict  # summary over the lines from JUDGED_FROM
    pooled_p95: float  # p95 of the distance over all judged lines' points together
    decisions: list[Decision] = field(default_factory=list)
    uploads: int = 0
    log: list[str] = field(default_factory=list)
    duration_s: float = 0.0
    sim: Simulation | None = None


class _Samples:
    """The pipeline's sink: /samples rows to the map provider; nothing else is kept."""

    def __init__(self, maps: RefitMaps) -> None:
        self.maps, self.last_t = maps, 0.0

    def write(self, topic: str, log_time_ns: int, message) -> None:  # type: ignore[no-untyped-def]
        if topic == "/samples":
            row = as_json(message)
            self.last_t = float(row["t"])
            self.maps.add(row)

    def metadata(self, name: str, data: dict[str, str]) -> None:
        pass


def fly(
    scenario: str = "river",
    seed: int = 2,
    replan: bool = True,
    effects: list[str] | None = None,
    boat: tuple[BoatParams, Gains] | None = None,
    duration_s: float = 1200.0,
    configure=None,  # type: ignore[no-untyped-def]  # called with the started Simulation
    provider=None,  # type: ignore[no-untyped-def]  # the maps (default: refitted on the samples so far)
    bound_m: float = 30.0,
    mission_file: str | None = None,
    judge: np.ndarray | None = None,
    on_upload=None,  # type: ignore[no-untyped-def]  # called with the link after each accepted upload
    on_decision=None,  # type: ignore[no-untyped-def]  # called with the Simulation and each decision
) -> Run:
    """Fly the lawnmower once (or ``mission_file``, scored on ``judge``: its survey lines, local m)
    with (or without) in-flight replanning; score the true track."""
    scen = sc.load(scenario)
    m = mission(scenario) if mission_file is None else ms.load(mission_file, scen)
    if mission_file is not None:  # the intended lines as `run --mission FILE` reads them
        lines_ll = read_mission(mission_file, scenario).lines_latlon
        m.lines = LocalFrame(scen.lat0, scen.lon0).points_to_local(lines_ll)
    sim = Simulation(scen, m, effects or [], seed=seed, boat_params=boat and boat[0],
                     gains=boat and boat[1])  # fmt: skip
    frame = LocalFrame(scen.lat0, scen.lon0)
    lo, hi = m.waypoints.min(axis=0) - 120.0, m.waypoints.max(axis=0) + 120.0
    maps = RefitMaps(scen.lat0, scen.lon0, (lo[0], hi[0], lo[1], hi[1]))
    samples = _Samples(maps)
    pipe = Pipeline(calibration.load(None), samples)
    log: list[str] = []
    pending: deque[Decision] = deque()
    rp: Replanner | None = None

    def on_message(msg) -> None:  # type: ignore[no-untyped-def]
        if rp is None:
            return
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            rp.heartbeat(md.MODE_NAMES.get(int(msg.custom_mode), str(msg.custom_mode)))
        elif kind == "GLOBAL_POSITION_INT" and msg.lat:
            d = rp.position(msg.lat * 1e-7, msg.lon * 1e-7, samples.last_t)
            if d is not None:
                pending.append(d)
        elif kind == "MISSION_CURRENT":
            d = rp.mission_current(int(msg.seq), samples.last_t)
            if d is not None:
                pending.append(d)

    link = OfflineLink(sim, on_message)

    def sink(source: str, t_ns: int, data: bytes) -> None:
        pipe.feed(source, t_ns, t_ns, data)
        if source == "mavlink":
            link.feed(data)

    sim.start(duration_s, sink)
    if configure is not None:
        configure(sim)
    if replan:
        lines_ll = frame.points_to_latlon(m.lines)  # type: ignore[arg-type]
        rp = Replanner(list(sim.autopilot.uplink.accepted), lines_ll, frame, BoatModel(),
                       provider or maps, bound_m=bound_m, log=log.append)  # fmt: skip
    decisions: list[Decision] = []
    while sim.t < duration_s and not (sim.nav.done and sim.mode == md.AUTO):
        sim.advance(sim.t + 0.5)
        while pending and rp is not None:
            d = pending.popleft()
            decisions.append(d)
            if on_decision is not None:
                on_decision(sim, d)
            if d.items is not None:
                sim.advance(sim.t + LATENCY_S)
                rp.note_latency(LATENCY_S)
                apply(rp, d, link, lambda: sim.t)
                if d.uploaded and on_upload is not None:
                    on_upload(link)
    pipe.close()
    sim.finish()
    return score(sim, m.lines if judge is None else judge, decisions, log)  # type: ignore[arg-type]


def score(sim: Simulation, lines: np.ndarray, decisions: list[Decision], log: list[str]) -> Run:
    tr = sim.track
    xy = np.column_stack([tr["x"], tr["y"]])
    sc_ = score_lines(tr["t"], xy, lines)
    judged = sc_[JUDGED_FROM:]
    d = []
    for a, b in lines[JUDGED_FROM:]:
        u = (b - a) / np.hypot(*(b - a))
        rel = xy - a
        along, across = rel @ u, np.abs(rel[:, 0] * u[1] - rel[:, 1] * u[0])
        vel = np.gradient(xy, axis=0) @ u
        on = (along >= 0) & (along <= np.hypot(*(b - a))) & (across < 10.0) & (vel > 0)
        d.append(across[on])
    pts = np.concatenate(d) if d else np.zeros(0)
    pooled = float(np.percentile(pts, 95)) if len(pts) else float("nan")
    return Run(
        [s.to_json() for s in sc_], summary(judged), pooled, decisions,
        sum(x.uploaded for x in decisions), log, float(tr["t"][-1]), sim,
    )  # fmt: skip
