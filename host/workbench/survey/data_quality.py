"""Data problems before physics: findings about the log itself, each with what the user can do about it.

`diagnose` and the report list these ahead of the physical candidates: a map fitted to interleaved
sources, false echoes or late time stamps explains the log, not the water. Five kinds:

- source conflict: a speed from successive positions far from SOG, or a heading that turns faster than a
  boat can: two sources feeding one column in turn (named from the log's ``columns`` metadata);
- spikes: the target's readings flagged along the track (host/workbench/survey/spikes.py);
- gaps: rows with no reading of the target, and where (host/workbench/survey/gaps.py): the maps use the rows that
  have it, never a filled value;
- latency: a source measured late against the position and the other sources whose latency stayed in
  the rows, and a wind or current vector steadiest in turns with the heading and ground velocity
  shifted (host/workbench/terms/clock_offset.py), blamed on the source the measured latencies name, or said
  to be undecidable where the log has none, with a note when the estimate is at the edge of the range;
- quantisation: positions on a coarse grid (a 3-decimal-minute position moves in 1.85 m steps).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.gaps import target_gaps
from forcemap.host.workbench.survey.instruments import Instruments, source_name
from forcemap.host.workbench.survey.table import Survey
from forcemap.host.workbench.survey.target_rows import target_flags, target_rows
from forcemap.host.workbench.terms import clock_offset

# speed from positions over this span is compared with SOG
SPAN_S = 1.0
# p95 of |speed from positions - SOG| beyond this: positions from more than one place (two receivers
# interleaved, or a glitching one). One receiver stays well below it (0.17 m/s on a real capture), and
# so does a 3-decimal-minute grid (at most 1.85 m in a second)
MAX_SPEED_MISMATCH = 2.5
# p99 of the turn rate from successive headings beyond this: two compasses interleaved (a small boat
# turns at most some 30 deg/s; one compass in a seaway reached 24 deg/s at p99)
MAX_TURN_RATE = 60.0
# a latency worth reporting: at least this offset, and this share of the vector's swing removed
MIN_LATENCY_S = 0.5
MIN_LATENCY_GAIN = 0.1
# a position grid coarser than this is reported
MIN_QUANTUM_M = 0.5


@dataclass
class DataFinding:
    kind: str  # "source conflict", "spikes", "gaps", "latency", "quantisation"
    text: str
    advice: str

    def to_json(self) -> dict:
        return {"kind": self.kind, "text": self.text, "advice": self.advice}

    def line(self) -> str:
        return f"{self.kind}: {self.text}. Advice: {self.advice}"


CHOOSE_SOURCE = (
    "choose one source per quantity ([sources] in the boat TOML; `forcemap log info` lists the "
    "sources and how they disagree), then import or run again"
)


def _span_pairs(t: np.ndarray, span: float) -> tuple[np.ndarray, np.ndarray]:
    """Row pairs (i, j) with t[j] the first time at least `span` after t[i]."""
    j = np.searchsorted(t, t + span)
    ok = j < len(t)
    return np.flatnonzero(ok), j[ok]


def speed_mismatch(survey: Survey) -> float | None:
    """p95 of |speed from positions over SPAN_S - mean SOG over the same span| (m/s); None without SOG."""
    sog = survey.columns.get("sog")
    if sog is None or not np.isfinite(sog).any():
        return None
    i, j = _span_pairs(survey.trel, SPAN_S)
    if len(i) < 10:
        return None
    xy, t = survey.xy, survey.trel
    v = np.hypot(*(xy[j] - xy[i]).T) / (t[j] - t[i])
    csum = np.concatenate([[0.0], np.cumsum(np.nan_to_num(sog))])
    mean_sog = (csum[j + 1] - csum[i]) / (j + 1 - i)
    d = np.abs(v - mean_sog)
    return float(np.nanpercentile(d, 95))


def turn_rate_p99(survey: Survey) -> float | None:
    """p99 of the turn rate (deg/s) between successive headings at least 0.1 s apart."""
    h = survey.columns.get("heading")
    if h is None or np.isfinite(h).sum() < 10:
        return None
    ok = np.isfinite(h)
    t, h = survey.trel[ok], h[ok]
    i, j = _span_pairs(t, 0.1)
    if len(i) < 10:
        return None
    rate = np.abs((h[j] - h[i] + 180.0) % 360.0 - 180.0) / (t[j] - t[i])
    return float(np.percentile(rate, 99))


def conflicts(survey: Survey, inst: Instruments) -> list[DataFinding]:
    """Position and heading sources that disagree, measured: two sentences of one receiver (GGA and RMC)
    feeding one column agree, and are no finding; the text names whatever fed the column."""
    out = []
    mismatch = speed_mismatch(survey)
    if mismatch is not None and mismatch > MAX_SPEED_MISMATCH:
        out.append(
            DataFinding(
                "source conflict",
                f"the speed from successive positions differs from SOG by {mismatch:.1f} m/s at p95 "
                f"(over {SPAN_S:g} s; one receiver stays well under {MAX_SPEED_MISMATCH:g}): positions from "
                f"more than one receiver interleaved ({inst.name('lat', 'the position source')})",
                CHOOSE_SOURCE,
            )
        )
    rate = turn_rate_p99(survey)
    if rate is not None and rate > MAX_TURN_RATE:
        out.append(
            DataFinding(
                "source conflict",
                f"the heading turns at {rate:.0f} deg/s at p99 (no survey boat turns faster than "
                f"{MAX_TURN_RATE:g}): two compasses interleaved? ({inst.name('heading', 'the heading')})",
                CHOOSE_SOURCE,
            )
        )
    return out


def spikes(survey: Survey, targets: list[str]) -> list[DataFinding]:
    out, seen = [], set()
    for target in targets:
        found = target_flags(survey, target)
        if found is None or not found.count or found.name in seen:
            continue
        seen.add(found.name)
        out += [DataFinding("spikes", line, found.advice()) for line in found.lines()]
    return out


def gaps(survey: Survey, targets: list[str]) -> list[DataFinding]:
    """The rows each target (a vector once) has no reading on, with their times."""
    out, seen = [], set()
    for target in targets:
        try:
            found = target_gaps(survey, target)
        except WorkbenchError:  # not a column of this table: nothing to say about its rows
            continue
        if not found.count or found.what in seen:
            continue
        seen.add(found.what)
        out.append(
            DataFinding(
                "gaps",
                found.line("its maps and diagnosis use the other {used:,}, never a filled value"),
                f"nothing to undo: if the gaps were not expected, check what measures the {found.what} "
                "and its cable at the times given",
            )
        )
    return out


CLOCK_HINT = "meanwhile the model term clock_offset undoes it"


def latency(survey: Survey, targets: list[str], inst: Instruments) -> list[DataFinding]:
    out, seen = [], set()
    for target in targets:
        vt = survey.vector_target(target)
        if vt is None or vt.prefix in seen or not clock_offset.applicable(survey, vt):
            continue
        seen.add(vt.prefix)
        try:
            # the rows the model's own scan runs on
            clean = target_rows(survey, target, clock_offset.AUTOPILOT_COLUMNS).survey
            scan = clock_offset.scan_offset(clean, vt)
        except WorkbenchError:
            continue
        tau = scan.offset_s
        if abs(tau) < MIN_LATENCY_S or scan.reduction < MIN_LATENCY_GAIN:
            continue
        text = (
            f"the {vt.prefix} vector is steadiest in turns with the heading and ground velocity taken "
            f"{tau:+.2f} s later ({scan.reduction:.0%} of its swing removed): "
            + _who_is_late(survey, inst, vt.family, tau)
        )
        if scan.at_edge:
            text += "; " + scan.edge_note()
        out.append(
            DataFinding(
                "latency",
                text,
                "fix the time stamp at the source (stamp at measurement, not on arrival; a shorter "
                f"buffer); {CLOCK_HINT}",
            )
        )
    return out


def _late_sources(survey: Survey) -> list[tuple[str, dict]]:
    """The navigation sources measured late (host/convert/navigation_table.latencies), latest first."""
    found = [
        (n, d)
        for n, d in survey.latencies.items()
        if d.get("latency") is not None and abs(d["latency"]) >= MIN_LATENCY_S
    ]
    return sorted(found, key=lambda x: -abs(x[1]["latency"]))


def _against(d: dict) -> str:
    named = {"position": "the course over ground", "speed over ground": "the speed over ground"}
    names = [named.get(a) or source_name(a) for a in d["against"]]
    return "measured against " + ", ".join(names) if names else "measured"


def _who_is_late(survey: Survey, inst: Instruments, family: str, tau: float) -> str:
    """Which source the evidence shows is late: the measured latencies where the log has them, else
    the two sides the offset is between, and that nothing tells which."""
    late = _late_sources(survey)
    kept = [(n, d) for n, d in late if not d.get("removed")]
    if kept:
        n, d = kept[0]
        return (
            f"the measured latencies name {source_name(n)}, {d['latency']:+.1f} s late "
            f"({_against(d)}), its latency not removed"
        )
    if late:
        names = ", ".join(f"{source_name(n)} {d['latency']:+.1f} s" for n, d in late)
        return f"left after the measured latencies were removed ({names}): not a source's latency"
    a, b = inst.navigation(), inst.boat_frame(family)
    if survey.latencies:
        return (
            f"no source's measured latency reaches {MIN_LATENCY_S:g} s, and nothing in the log tells "
            f"which of {a} and {b} is late"
        )
    return f"nothing in the log tells which of {a} and {b} is late"


def measured_latency(survey: Survey) -> list[DataFinding]:
    """Sources measured late whose latency was kept in the rows ([sync] latency = "keep")."""
    out = []
    for n, d in _late_sources(survey):
        if d.get("removed"):
            continue
        out.append(
            DataFinding(
                "latency",
                f"{source_name(n)} is {d['latency']:+.1f} s late ({d['quantity']}; {_against(d)}); "
                "its latency is not removed, so every vector it turns or subtracts is of another "
                "moment",
                'remove it: [sync] latency = "remove" in the boat TOML (the default), or fix the '
                "time stamp at the source",
            )
        )
    return out


def _m_per_minute(survey: Survey) -> float:
    """Metres per minute of latitude at the survey's centre (WGS-84)."""
    return LocalFrame(survey.lat0, survey.lon0).m_per_deg_lat / 60.0


def position_quantum_m(survey: Survey) -> float | None:
    """The step (m) of a position grid in decimal minutes the latitudes sit on, if it is coarse."""
    lat = survey.columns["lat"]
    minutes = np.abs(lat) * 60.0
    for decimals in (1, 2, 3, 4):
        scaled = minutes * 10.0**decimals
        if np.all(np.abs(scaled - np.round(scaled)) < 0.01):
            step = _m_per_minute(survey) * 10.0**-decimals
            return step if step >= MIN_QUANTUM_M else None
    return None


def quantisation(survey: Survey, inst: Instruments) -> list[DataFinding]:
    step = position_quantum_m(survey)
    if step is None:
        return []
    decimals = round(-math.log10(step / _m_per_minute(survey)))
    return [
        DataFinding(
            "quantisation",
            f"positions are on a grid of 0.{'0' * (decimals - 1)}1 minute ({step:.2f} m steps in "
            f"latitude) from {inst.name('lat', 'the position source')}: the speed from successive "
            "positions jumps by a step, and the map cannot resolve less",
            "take the position from a source that sends more decimals (the GNSS itself rather than an "
            "instrument bus that re-sends it), or use SOG and COG rather than differences of positions",
        )
    ]


def findings(survey: Survey, targets: list[str]) -> list[DataFinding]:
    """Every data-quality finding about the survey and the given targets, conflicts first."""
    inst = Instruments.of(survey)
    return (
        conflicts(survey, inst)
        + gaps(survey, targets)
        + spikes(survey, targets)
        + measured_latency(survey)
        + latency(survey, targets, inst)
        + quantisation(survey, inst)
    )
