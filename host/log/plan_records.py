"""The planner's records in the log: `/plan/replan`, one per in-flight replanning decision (issue 22).

`messages.TOPIC_TYPES` maps the topic to it; `messages.Replan` is the same class.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from forcemap.host.log.record import Record

Opt = float | None


@dataclass(slots=True)
class Replan(Record):
    """One in-flight replanning decision (host/plan/inflight.py), uploaded or not."""

    NAME = "forcemap.Replan"
    DESCRIPTION = (
        "In-flight replanning after an intended line: the remaining mission before and after "
        "([lat, lon, ground speed m/s or null] per waypoint), the predicted worst-line p95 "
        "distance (m) and coverage of each, the map's age (s), and why it was uploaded or not"
    )
    t: float
    line_done: int  # index of the intended line just finished
    mode: str
    uploaded: bool
    reason: str
    first_seq: int | None = None  # first mission item replaced
    old_remaining: list[list[float | None]] = field(default_factory=list)
    new_remaining: list[list[float | None]] = field(default_factory=list)
    old_p95_m: Opt = None
    new_p95_m: Opt = None
    old_coverage: Opt = None
    new_coverage: Opt = None
    map_age_s: Opt = None
    map_samples: int | None = None
    current_mean_mps: Opt = None  # mapped current speed, mean along all intended lines
    clipped: int = 0  # waypoints moved back within the bounds
    clipped_max_m: float = 0.0
    cpu_s: Opt = None  # the decision's CPU time, without the map's
    map_cpu_s: Opt = None  # getting the maps (a refit of the samples so far)
    late: bool = False  # it missed its turn: the boat was on the next line first (t: decided at)
    refused: bool = False  # the autopilot refused the upload, or did not answer it
    turn_end_t: Opt = None  # when the turn it was for ended, if it was late


def replan_counts(records: list[dict]) -> dict[str, int]:
    """How many /plan/replan decisions were made, uploaded, late (missed their turn) and refused (the
    autopilot refused the upload or did not answer it)."""
    return {
        "made": len(records),
        "uploaded": sum(bool(r.get("uploaded")) for r in records),
        "late": sum(bool(r.get("late")) for r in records),
        "refused": sum(bool(r.get("refused")) for r in records),
    }


def describe_counts(records: list[dict]) -> str:
    """'5 decisions made, 3 uploaded, 1 late, 1 refused'."""
    c = replan_counts(records)
    return f"{c['made']} decisions made, {c['uploaded']} uploaded, {c['late']} late, {c['refused']} refused"
