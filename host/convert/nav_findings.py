"""Each navigation source's latency, noise, bias and outliers as quality findings (``qa.*`` metadata).

An import keeps the navigation readings as they go to the log (``Collector``, a pipeline sink in
front of the MCAP), smooths them once the pipeline has closed, and writes one
forcemap.host.log.qa_records.QaFinding per source (check ``latency``) before the file is closed, so
that `forcemap check` and `log info` read them. A log without them (a live run's) has them
computed when `log info` asks (forcemap.host.convert.navigation_table.fitted).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from forcemap.host.convert import nav_readings
from forcemap.host.convert.navigation import Navigation, SourceFit
from forcemap.host.log.messages import as_json
from forcemap.host.log.qa_records import QaFinding, is_finding

CATEGORY = {
    "position": "position",
    "velocity": "position",
    "heading": "heading",
    "yaw_rate": "rate_of_turn",
    "stw": "speed_through_water",
}
LATE_S = 0.5  # a latency from here on is worth a word (host/workbench/data_quality.MIN_LATENCY_S)
POSITION_TYPES = ("RMC", "GGA", "GLL", "GNS")


class Collector:
    """A pipeline sink in front of another: forwards everything, keeps the navigation readings."""

    def __init__(self, sink: Any) -> None:
        self.sink = sink
        self.messages: list[tuple[str, int, dict]] = []
        self.times: list[float] = []

    def write(self, topic: str, log_time_ns: int, message: Any) -> None:
        self.sink.write(topic, log_time_ns, message)
        if topic == "/source/reading" or (
            topic == "/nmea/sentence" and getattr(message, "type", "") in POSITION_TYPES
        ):
            self.messages.append((topic, log_time_ns, as_json(message)))
        elif topic == "/samples":
            self.times.append(log_time_ns * 1e-9)

    def metadata(self, name: str, data: dict[str, str]) -> None:
        self.sink.metadata(name, data)

    def write_findings(self, remove_latency: bool) -> list[QaFinding]:
        """Smooth what was kept and write a finding per source into the sink's metadata."""
        readings = nav_readings.collect(self.messages)
        if "position" not in readings or not self.times:
            return []
        nav = Navigation(remove_latency=remove_latency).fit(readings, np.asarray(self.times))
        out = findings(nav)
        for f in out:
            self.sink.metadata(f.name, f.to_metadata())
        return out


def _verdict(f: SourceFit) -> str:
    if f.latency is None:  # not measurable: the message says so; no evidence of a problem
        return "green"
    if abs(f.latency) < LATE_S:
        return "green"
    return "yellow" if f.applied else "red"


def _num(x: float | None, fmt: str) -> str:
    return "?" if x is None or not math.isfinite(x) else format(x, fmt)


def finding(f: SourceFit) -> QaFinding:
    """One source's fit as a finding: the latency its value, noise, bias, outliers in its text."""
    source = f.source + (" (velocity)" if f.quantity == "velocity" else "")
    if f.quantity == "position":
        lat = "the time reference"
    elif f.latency is None:
        lat = f"latency not measured: {f.latency_note or 'nothing in the log can tell'}"
    else:
        sd = f" +- {f.latency_sd:.2f}" if f.latency_sd is not None else ""
        done = "removed" if f.applied else "kept"
        lat = f"latency {f.latency:+.2f}{sd} s ({done})"
    msg = (
        f"{source}: {lat}; noise {_num(f.noise, '.3g')} {f.unit}, bias {_num(f.bias, '+.3g')} "
        f"{f.unit}, {f.outliers} outliers of {f.readings}"
    )
    against = ", ".join(f"{a} {lag:+.2f} s" for a, lag in f.pairs)
    fix = ""
    if f.latency is not None and abs(f.latency) >= LATE_S:
        fix = (
            f"applied: readings taken {f.latency:+.2f} s earlier"
            if f.applied
            else 'kept ([sync] latency = "keep"); fix the time stamp at the source'
        )
    return QaFinding(
        CATEGORY[f.quantity],
        "latency",
        _verdict(f),
        msg,
        source=source,
        value=math.nan if f.latency is None else float(f.latency),
        sd=math.nan if f.latency_sd is None else float(f.latency_sd),
        unit="s",
        threshold=f"|latency| < {LATE_S:g} s",
        evidence=f"lags against {against}" if against else (f.latency_note or "the time reference"),
        fix=fix,
        applied=f.applied,
        extra={
            "noise": _num(f.noise, ".6g"),
            "noise_unit": f.unit,
            "bias": _num(f.bias, ".6g"),
            "outliers": str(f.outliers),
            "readings": str(f.readings),
            "quantity": f.quantity,
        },
    )


def findings(nav: Navigation) -> list[QaFinding]:
    return [finding(f) for f in nav.fits_ if f.quantity in CATEGORY]


def log_findings(
    paths: Sequence[str | os.PathLike[str]], compute: bool = True
) -> list[QaFinding]:
    """The logs' navigation findings: as the import wrote them, else computed now (``compute``)."""
    from forcemap.host.log.mcap import iter_metadata

    found: dict[str, QaFinding] = {}
    for path in paths:
        for name, data in iter_metadata(path):
            if is_finding(name):
                f = QaFinding.from_metadata(data)
                if f.check == "latency" and "noise" in f.extra:
                    found[name] = f
    if found or not compute:
        return list(found.values())
    from forcemap.host.convert.navigation_table import fitted

    nav = fitted(paths)
    return findings(nav) if nav is not None else []


def not_smoothed_line() -> list[str]:
    return [
        "",
        "  navigation sources: none smoothed (no position reading, or a log it cannot solve)",
    ]


def lines(found: list[QaFinding]) -> list[str]:
    """`log info`'s navigation section: one line per source."""
    if not found:
        return not_smoothed_line()
    out = ["", "  navigation sources (smoothed from every source; latency, noise, bias, outliers):"]
    for f in found:
        out.append(f"    [{f.verdict:<6}] {f.message}")
    return out


def navigation_json(path: str) -> list[dict[str, str]]:
    """`log info --json`'s navigation: each source's finding as its metadata record."""
    try:
        return [f.to_metadata() for f in log_findings([path])]
    except (OSError, ValueError):
        return []
