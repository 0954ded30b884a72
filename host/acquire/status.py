"""The daemon's live status: counters and rates, drawn on a terminal or written as JSON lines."""

from __future__ import annotations

import json
import sys
import time
from collections import deque
from collections.abc import Mapping
from typing import Any, TextIO

from forcemap.host.acquire.sources import ReaderStats


def _human_bytes(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(n) < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GiB"


def flatten(value: Any, prefix: str = "") -> dict[str, Any]:
    """Nested dicts to ``{"a.b": leaf}``; lists and other leaves are kept as they are."""
    if not isinstance(value, Mapping):
        return {prefix or "value": value}
    out: dict[str, Any] = {}
    for k, v in value.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, Mapping):
            out.update(flatten(v, key))
        else:
            out[key] = v
    return out


class Status:
    """Collects what the daemon knows: per-source readers, per-topic messages, errors, last fix."""

    def __init__(self, readers: Mapping[str, ReaderStats], absent: list[str] | None = None):
        self.readers = readers
        self.absent = list(absent or [])
        self.started = time.monotonic()
        self.topic_counts: dict[str, int] = {}
        self.errors: dict[str, int] = {}
        self.last_fix: dict[str, Any] | None = None
        self.pipeline_counters: dict[str, Any] = {}
        self.file = ""
        self.file_bytes = 0
        self.files = 0
        self._prev_t = self.started
        self._prev_bytes: dict[str, int] = {}
        self._prev_topics: dict[str, int] = {}
        self.rates: dict[str, float] = {}
        self.topic_rates: dict[str, float] = {}
        self.stopping = False

    def observe(self, topic: str, message: Mapping[str, Any]) -> None:
        """Called for every logged message."""
        self.topic_counts[topic] = self.topic_counts.get(topic, 0) + 1
        if topic == "/fix":
            self.last_fix = dict(message)

    def error(self, reason: str) -> None:
        self.errors[reason] = self.errors.get(reason, 0) + 1

    def update_rates(self) -> None:
        """Recompute bytes/s per source and messages/s per topic since the previous call."""
        now = time.monotonic()
        dt = now - self._prev_t
        if dt < 0.5:  # too short a window for a meaningful rate (e.g. the final update)
            return
        for name, st in self.readers.items():
            self.rates[name] = (st.bytes - self._prev_bytes.get(name, 0)) / dt
            self._prev_bytes[name] = st.bytes
        for topic, n in self.topic_counts.items():
            self.topic_rates[topic] = (n - self._prev_topics.get(topic, 0)) / dt
        self._prev_topics = dict(self.topic_counts)
        self._prev_t = now

    def snapshot(self) -> dict[str, Any]:
        """A JSON-able summary; also what ``/daemon/status`` records."""
        sources = {}
        for name, st in self.readers.items():
            sources[name] = {
                "connected": st.connected,
                "bytes": st.bytes,
                "chunks": st.chunks,
                "bytes_per_s": round(self.rates.get(name, 0.0), 1),
                "connects": st.connects,
                "disconnects": st.disconnects,
                "errors": dict(st.errors),
                "queue_drops": st.queue_drops,
            }
        fix = None
        if self.last_fix is not None:
            fix = {k: self.last_fix.get(k) for k in ("latitude", "longitude") if k in self.last_fix}
        return {
            "uptime_s": round(time.monotonic() - self.started, 1),
            "sources": sources,
            "absent": self.absent,
            "messages": dict(self.topic_counts),
            "errors": dict(self.errors),
            "pipeline": self.pipeline_counters,
            "last_fix": fix,
            "file": self.file,
            "file_bytes": self.file_bytes,
            "files": self.files,
        }

    def screen(self) -> str:
        """The multi-line terminal view."""
        lines = [
            f"forcemap run  up {time.monotonic() - self.started:7.0f} s   "
            f"{self.file}  {_human_bytes(self.file_bytes)}"
            + (f" ({self.files} files)" if self.files > 1 else ""),
            "",
            f"{'source':<10}{'state':<14}{'rate':>12}{'total':>12}{'reconnects':>12}  errors",
        ]
        for name, st in self.readers.items():
            state = "stopped" if self.stopping else ("reading" if st.connected else "WAITING")
            errs = ", ".join(f"{k} {v}" for k, v in sorted(st.errors.items())) or "-"
            lines.append(
                f"{name:<10}{state:<14}{_human_bytes(self.rates.get(name, 0.0)) + '/s':>12}"
                f"{_human_bytes(st.bytes):>12}{max(st.connects - 1, 0):>12}  {errs}"
            )
        for name in self.absent:
            lines.append(f"{name:<10}{'not given':<14}")
        lines.append("")
        topics = sorted(self.topic_counts)
        if topics:
            lines.append(f"{'topic':<22}{'msg/s':>8}{'total':>10}")
            for t in topics:
                lines.append(
                    f"{t:<22}{self.topic_rates.get(t, 0.0):>8.1f}{self.topic_counts[t]:>10}"
                )
            lines.append("")
        if self.last_fix:
            lat, lon = self.last_fix.get("latitude"), self.last_fix.get("longitude")
            if isinstance(lat, int | float) and isinstance(lon, int | float):
                lines.append(f"last fix  {lat:.6f}, {lon:.6f}")
        else:
            lines.append("last fix  none yet")
        errors = {**self.errors, **_pipeline_errors(self.pipeline_counters)}
        if errors:
            lines.append("errors    " + ", ".join(f"{k} {v}" for k, v in sorted(errors.items())))
        return "\n".join(lines)


def _pipeline_errors(counters: Mapping[str, Any]) -> dict[str, Any]:
    flat = flatten(counters) if counters else {}
    words = ("reject", "error", "bad", "crc", "invalid", "gap", "drop")
    return {
        k: v
        for k, v in flat.items()
        if isinstance(v, int | float) and v and any(w in k.lower() for w in words)
    }


class Reporter:
    """Where status and events go: a redrawn terminal view, or one JSON line per event."""

    def __init__(self, stream: TextIO | None = None, *, live: bool | None = None):
        self.stream = stream or sys.stderr
        self.live = self.stream.isatty() if live is None else live
        self.summary_every_s = 60.0
        self._last_summary = time.monotonic()
        self.recent: deque[str] = deque(maxlen=8)

    def event(self, event: str, **fields: Any) -> None:
        """One event: a JSON line in structured mode, a plain line above the live view otherwise."""
        record = {"ts": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "event": event}
        record.update(fields)
        if self.live:
            detail = " ".join(f"{k}={v}" for k, v in fields.items())
            self.recent.append(f"{record['ts']} {event} {detail}"[:160])
        else:
            self._write(json.dumps(record, default=str, separators=(",", ":")) + "\n")

    def status(self, status: Status, *, final: bool = False) -> None:
        """Redraw the live view, or write a summary line every minute (and at the end)."""
        if self.live and not final:
            recent = "\n".join(["", "recent events", *self.recent]) if self.recent else ""
            self._write("\x1b[H\x1b[J" + status.screen() + recent + "\n")
            return
        now = time.monotonic()
        if final and self.live:
            self._write("\n".join(self.recent) + "\n" + status.screen() + "\n")
            return
        if final or now - self._last_summary >= self.summary_every_s:
            self._last_summary = now
            self.event("final_status" if final else "status", **status.snapshot())

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            pass  # a closed terminal must not stop the daemon
