"""What an MCAP log holds (`forcemap log info`): topics, rates, gaps, outages, error counters, the two
true-wind routes, the sources per quantity and the in-flight replans; and its repair (`log recover`): every readable record
copied into a complete file."""

from __future__ import annotations

import bisect
import json
import os
import statistics
from array import array
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from forcemap.host.acquire.status import flatten
from forcemap.host.convert.nav_findings import navigation_json
from forcemap.host.convert.sources_info import SourceCollector
from forcemap.host.log.mcap import CHUNK_SIZE, LIBRARY, FileScan, iter_records
from forcemap.host.log.qa_records import QaFinding, is_finding
from forcemap.host.vessel.geodesy import wrap_from_minus180
from mcap.records import Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

# a topic has a gap where consecutive messages are further apart than this many mean periods
GAP_FACTOR = 10.0
MIN_GAP_S = 2.0
WIND_PAIR_S = 2.0  # an instrument true wind and a computed one this close in time are compared
# counters whose names contain one of these are shown by `info`
ERROR_WORDS = (
    "reject",
    "error",
    "bad",
    "crc",
    "junk",
    "lost",
    "gap",
    "reset",
    "drop",
    "internal",
    "without",
)


@dataclass
class TopicInfo:
    """Per-topic counts and the timing needed to find gaps."""

    schema: str = ""
    count: int = 0
    first_ns: int = 0
    last_ns: int = 0
    times: array = field(default_factory=lambda: array("q"))


@dataclass
class LogInfo:
    """What `log info` reports about one file."""

    path: str
    size: int
    complete: bool
    truncated: bool
    error: str
    library: str = ""
    topics: dict[str, TopicInfo] = field(default_factory=dict)
    metadata: list[str] = field(default_factory=list)
    events: list[tuple[int, dict[str, Any]]] = field(default_factory=list)
    last_diagnostics: dict[str, Any] | None = None
    last_status: dict[str, Any] | None = None
    columns: dict[str, str] = field(default_factory=dict)
    winds: dict[str, list[tuple[float, float, float]]] = field(default_factory=dict)
    sources: SourceCollector = field(default_factory=SourceCollector)
    replans: list[dict[str, Any]] = field(default_factory=list)  # /plan/replan, in order
    findings: dict[str, QaFinding] = field(default_factory=dict)  # qa.* metadata, by name

    @property
    def start_ns(self) -> int:
        return min((t.first_ns for t in self.topics.values() if t.count), default=0)

    @property
    def end_ns(self) -> int:
        return max((t.last_ns for t in self.topics.values() if t.count), default=0)

    def gaps(self) -> list[tuple[str, float, float]]:
        """(topic, start UNIX s, length s) where a regular topic went quiet.

        Quiet means longer than GAP_FACTOR mean periods and at least MIN_GAP_S: sources that
        send in bursts (an NMEA talker's sentences) are judged by their mean rate, not the median.
        """
        out = []
        for topic, ti in self.topics.items():
            if topic.startswith("/daemon/") or len(ti.times) < 10:
                continue
            times = sorted(ti.times)
            mean = (times[-1] - times[0]) / (len(times) - 1)
            limit = max(GAP_FACTOR * mean, MIN_GAP_S * 1e9)
            for a, b in zip(times, times[1:], strict=False):
                if b - a > limit:
                    out.append((topic, a / 1e9, (b - a) / 1e9))
        return sorted(out, key=lambda g: g[1])

    def outages(self) -> list[dict[str, Any]]:
        """Source disconnections recorded by the daemon, with how long each lasted."""
        out: list[dict[str, Any]] = []
        down: dict[str, tuple[int, str]] = {}
        for t, ev in self.events:
            source = ev.get("source")
            if ev.get("event") == "disconnected" and source:
                down.setdefault(source, (t, ev.get("reason", "")))
            elif ev.get("event") == "connected" and source in down:
                t0, reason = down.pop(source)
                out.append(
                    {"source": source, "start_ns": t0, "length_s": (t - t0) / 1e9, "reason": reason}
                )
        for source, (t0, reason) in down.items():
            out.append({"source": source, "start_ns": t0, "length_s": None, "reason": reason})
        return out

    def error_counters(self) -> dict[str, Any]:
        """Non-zero counters of errors, rejections and gaps: the pipeline's last /diagnostics
        (or the daemon's last status if there is none) and the readers' errors by reason."""
        out: dict[str, Any] = {}
        counters = None
        if self.last_diagnostics:
            counters = self.last_diagnostics.get("counters", self.last_diagnostics)
        elif self.last_status:
            counters = self.last_status.get("pipeline")
        for k, v in flatten(counters or {}).items():
            if _nz(v) and any(w in k.lower() for w in ERROR_WORDS):
                out[k] = v
        if self.last_status:
            for k, v in (self.last_status.get("errors") or {}).items():
                out[f"daemon.{k}"] = v
            for name, src in (self.last_status.get("sources") or {}).items():
                for reason, n in (src.get("errors") or {}).items():
                    out[f"port.{name}.{reason}"] = n
        return out


def _nz(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and v != 0


def scan_file(path: str | os.PathLike[str]) -> LogInfo:
    """Read a whole file (complete or truncated) and gather what `info` shows."""
    scan = FileScan(Path(path))
    info = LogInfo(str(path), os.path.getsize(path), False, False, "")
    for record in iter_records(path, scan):
        if isinstance(record, Message):
            channel = scan.channels.get(record.channel_id)
            if channel is None:
                continue
            ti = info.topics.get(channel.topic)
            if ti is None:
                schema = scan.schemas.get(channel.schema_id)
                ti = info.topics[channel.topic] = TopicInfo(schema.name if schema else "")
                ti.first_ns = record.log_time
            ti.count += 1
            ti.first_ns = min(ti.first_ns, record.log_time)
            ti.last_ns = max(ti.last_ns, record.log_time)
            ti.times.append(record.log_time)
            if channel.topic == "/source/reading":
                info.sources.add(record.log_time, record.data)
            elif channel.topic == "/wind/true":
                _add_wind(info, record.data)
            elif channel.topic == "/plan/replan":
                try:
                    info.replans.append(json.loads(record.data))
                except ValueError:
                    continue
            elif channel.topic in ("/diagnostics", "/daemon/status", "/daemon/event"):
                try:
                    msg = json.loads(record.data)
                except ValueError:
                    continue
                if channel.topic == "/diagnostics":
                    info.last_diagnostics = msg
                elif channel.topic == "/daemon/status":
                    info.last_status = msg
                else:
                    info.events.append((record.log_time, msg))
        elif isinstance(record, Metadata):
            info.metadata.append(record.name)
            if record.name == "columns":
                info.columns = dict(record.metadata)
            elif record.name == "sources":
                info.sources.metadata(dict(record.metadata))
            elif is_finding(record.name):
                info.findings[record.name] = QaFinding.from_metadata(dict(record.metadata))
    info.complete = scan.complete and not scan.truncated
    info.truncated = scan.truncated
    info.error = scan.error
    return info


def _add_wind(info: LogInfo, data: bytes) -> None:
    try:
        m = json.loads(data)
    except ValueError:
        return
    if isinstance(m.get("speed"), int | float) and isinstance(m.get("dir"), int | float):
        route = m.get("route") or "computed"
        info.winds.setdefault(route, []).append((float(m["t"]), m["speed"], m["dir"]))


def wind_routes(info: LogInfo, max_dt: float = WIND_PAIR_S) -> dict[str, Any] | None:
    """How the instrument's true wind differs from the computed one, over pairs close in time."""
    comp, inst = sorted(info.winds.get("computed", [])), info.winds.get("instrument", [])
    if not comp or not inst:
        return None
    times = [c[0] for c in comp]
    ds, dd = [], []
    for t, speed, direction in inst:
        i = bisect.bisect_left(times, t)
        near = [c for c in comp[max(i - 1, 0) : i + 1] if abs(c[0] - t) <= max_dt]
        if near:
            c = min(near, key=lambda c: abs(c[0] - t))
            ds.append(speed - c[1])
            dd.append(float(wrap_from_minus180(direction - c[2])))
    if not ds:
        return {"pairs": 0}
    return {
        "pairs": len(ds),
        "speed_mean": statistics.fmean(ds),
        "speed_median_abs": statistics.median(abs(x) for x in ds),
        "dir_mean": statistics.fmean(dd),
        "dir_median_abs": statistics.median(abs(x) for x in dd),
    }


def info_json(info: LogInfo) -> dict[str, Any]:
    return {
        "path": info.path,
        "size": info.size,
        "complete": info.complete,
        "truncated": info.truncated,
        "error": info.error,
        "start_ns": info.start_ns,
        "end_ns": info.end_ns,
        "metadata": info.metadata,
        "topics": {
            t: {
                "schema": ti.schema,
                "count": ti.count,
                "first_ns": ti.first_ns,
                "last_ns": ti.last_ns,
            }
            for t, ti in info.topics.items()
        },
        "outages": info.outages(),
        "gaps": [{"topic": t, "start": s, "length_s": g} for t, s, g in info.gaps()],
        "errors": info.error_counters(),
        "columns": info.columns,
        "true_wind_routes": wind_routes(info),
        "sources": info.sources.result(),
        "replans": info.replans,
        "findings": {n: f.to_metadata() for n, f in info.findings.items()},
        "navigation": navigation_json(info.path),
    }


def recover(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> tuple[int, FileScan]:
    """Copy every readable record of ``src`` into a new, complete ``dst``. Returns (messages, scan)."""
    scan = FileScan(Path(src))
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    count = 0
    tmp = Path(f"{dst}.tmp")
    with open(tmp, "wb") as f:
        writer = Writer(f, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
        writer.start(profile="", library=f"{LIBRARY} log recover")
        for record in iter_records(src, scan):
            if isinstance(record, Schema):
                if record.id not in schema_ids:
                    schema_ids[record.id] = writer.register_schema(
                        record.name, record.encoding, record.data
                    )
            elif isinstance(record, Message):
                channel = scan.channels.get(record.channel_id)
                if channel is None:
                    continue
                if channel.id not in channel_ids:
                    channel_ids[channel.id] = writer.register_channel(
                        channel.topic,
                        channel.message_encoding,
                        schema_ids.get(channel.schema_id, 0),
                        dict(channel.metadata),
                    )
                writer.add_message(
                    channel_ids[channel.id],
                    record.log_time,
                    record.data,
                    record.publish_time,
                    record.sequence,
                )
                count += 1
            elif isinstance(record, Metadata):
                writer.add_metadata(record.name, dict(record.metadata))
        for att in scan.attachments:
            writer.add_attachment(att.create_time, att.log_time, att.name, att.media_type, att.data)
        writer.finish()
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, dst)
    return count, scan
