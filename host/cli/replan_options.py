"""`forcemap run --replan`: its options, the replanner's service wired to the daemon, and the sink that hands
it every /samples row (issue 22; docs/PLAN.md)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from forcemap.host.cli.common import positive
from forcemap.host.errors import CliError


def add_replan_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--mission",
        metavar="MISSION",
        help="with --replan: the mission the autopilot flies (QGC WPL 110, QGC .plan or simulator "
        "TOML; its survey lines from MISSION.json if it was planned, a .plan's survey transects, "
        "else its long parallel legs); checked against the autopilot's copy (default: the "
        "autopilot's mission, read back)",
    )
    parser.add_argument(
        "--replan",
        action="store_true",
        help="after each survey line, plan the rest of the mission on the maps so far and upload "
        "it when it is predicted to hold the lines better (needs --mavlink; docs/PLAN.md)",
    )
    parser.add_argument(
        "--replan-terms",
        metavar="TERMS",
        help="with --replan: the refit's terms beyond the baseline, comma-separated (e.g. tide: the "
        "rest of the mission is planned in the current the tide will bring when the boat is on each "
        "line; default none: the mapped current so far)",
    )
    parser.add_argument(
        "--replan-bound",
        type=float,
        default=30.0,
        metavar="M",
        help="with --replan: largest move of a waypoint across its line (default 30 m)",
    )


class SampleTee:
    """The pipeline's sink, with every /samples row also handed to ``on_sample`` (the replanner)."""

    def __init__(self, sink: Any, on_sample: Callable[[dict], object]) -> None:
        self.sink, self.on_sample = sink, on_sample

    def write(self, topic: str, log_time_ns: int, message: Any) -> None:
        self.sink.write(topic, log_time_ns, message)
        if topic == "/samples":
            self.on_sample(message.to_json())

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.sink.metadata(name, data)

    def failed(self, *a: Any, **kw: Any) -> None:
        self.sink.failed(*a, **kw)


def replan_service(args: argparse.Namespace) -> Any:
    """The replanner's thread for --replan (not started), or None; a bad combination is a CliError."""
    if not args.replan:
        if args.mission:
            raise CliError("--mission is only used with --replan")
        return None
    if not args.mavlink:
        raise CliError(
            "--replan needs --mavlink: the autopilot to read the mission from and upload to"
        )
    positive("--replan-bound", args.replan_bound)
    from forcemap.host.workbench.terms.spec import BASELINE, check_terms, split_effects

    terms = None
    if getattr(args, "replan_terms", None):
        terms = list(BASELINE) + [t for t in split_effects(args.replan_terms) if t not in BASELINE]
        check_terms(terms)
    from forcemap.host.plan.boat_model import load_boat
    from forcemap.host.plan.mission_io import read_mission
    from forcemap.host.plan.service import ReplanService

    mission = read_mission(args.mission) if args.mission else None
    box: dict[str, Any] = {}

    def send(data: bytes) -> bool:
        return box["daemon"].readers["mavlink"].write(data)

    def record(rec: Any) -> None:
        box["daemon"].post("/plan/replan", rec)

    def log(text: str) -> None:
        from forcemap.host.log.messages import DaemonEvent

        d = box.get("daemon")
        if d is not None:
            d.post("/daemon/event", DaemonEvent("replan", {"message": text}))

    svc = ReplanService(
        mission, load_boat(None), send, record, log, bound_m=args.replan_bound, terms=terms
    )
    svc.box = box  # type: ignore[attr-defined]
    return svc
