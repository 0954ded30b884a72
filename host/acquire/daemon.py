"""The acquisition loop: reader threads → queue → pipeline → MCAP, surviving any one instrument."""

from __future__ import annotations

import base64
import queue
import threading
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from forcemap.host.acquire.arrival_clock import Clock, SystemClock
from forcemap.host.acquire.sources import Chunk, Reader, SourceEvent, Transport
from forcemap.host.acquire.status import Reporter, Status
from forcemap.host.log.mcap import McapLog
from forcemap.host.log.messages import DaemonEvent, DaemonStatus, RawChunk, Record, as_json

STATUS_INTERVAL_S = 1.0
QUEUE_MAX = 100_000
# errors of one kind are reported as events the first few times, then only counted
EVENT_REPORT_LIMIT = 5


class PipelineLike(Protocol):
    """What the daemon needs from ``host.pipeline.Pipeline``."""

    def feed(self, source: str, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None: ...

    def gap(self, source: str, t_wall_ns: int, reason: str) -> None: ...

    def counters(self) -> dict: ...

    def flush(self) -> None: ...

    def close(self) -> None: ...


class ObservedSink:
    """The sink handed to the pipeline: writes to the log, tells the status, never raises."""

    def __init__(self, log: McapLog, status: Status, reporter: Reporter):
        self.log = log
        self.status = status
        self.reporter = reporter
        self._reported: dict[str, int] = {}

    def write(self, topic: str, log_time_ns: int, message: Record) -> None:
        try:
            self.log.write(topic, log_time_ns, message)
        except Exception as exc:
            self.failed("log_write", exc, topic=topic)
            return
        self.status.observe(topic, as_json(message))

    def metadata(self, name: str, data: dict[str, str]) -> None:
        try:
            self.log.metadata(name, data)
        except Exception as exc:
            self.failed("log_metadata", exc, name=name)

    def failed(self, reason: str, exc: BaseException, **fields: Any) -> None:
        """Count an error; report the first few of each kind as events (with a traceback)."""
        self.status.error(reason)
        n = self._reported.get(reason, 0) + 1
        self._reported[reason] = n
        if n <= EVENT_REPORT_LIMIT:
            tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
            self.reporter.event("error", reason=reason, error=tb, count=n, **fields)


def raw_message(chunk: Chunk) -> RawChunk:
    """A ``/raw/<source>`` message: the bytes as read (base64) with their arrival stamps."""
    data = base64.b64encode(chunk.data).decode("ascii")
    return RawChunk(chunk.t_mono_ns, chunk.t_wall_ns, data)


class RawOnly:
    """Stands in when the pipeline cannot be built: nothing parsed, the raw bytes are logged."""

    def feed(self, source: str, t_mono_ns: int, t_wall_ns: int, data: bytes) -> None:
        pass

    def gap(self, source: str, t_wall_ns: int, reason: str) -> None:
        pass

    def counters(self) -> dict:
        return {"pipeline": "unavailable: raw bytes only"}

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


@dataclass
class Posted:
    """A record handed over by another thread (the replanner) for the log."""

    topic: str
    t_wall_ns: int
    record: Record


class Daemon:
    """Runs readers for the given sources and feeds their bytes to the pipeline until stopped."""

    def __init__(
        self,
        openers: Mapping[str, Callable[[], Transport]],
        make_pipeline: Callable[[ObservedSink], PipelineLike],
        log: McapLog,
        *,
        clock: Clock | None = None,
        reporter: Reporter | None = None,
        absent: list[str] | None = None,
        status_interval_s: float = STATUS_INTERVAL_S,
        record_raw: bool = False,
        taps: Mapping[str, Callable[[bytes], object]] | None = None,
    ):
        self.clock = clock or SystemClock()
        self.record_raw = record_raw
        self.taps = dict(taps or {})  # source -> a quick, non-blocking consumer of its bytes
        self.log = log
        self.reporter = reporter or Reporter()
        self.stop_event = threading.Event()
        self.queue: queue.Queue[Chunk | SourceEvent] = queue.Queue(maxsize=QUEUE_MAX)
        self.readers = {
            name: Reader(name, opener, self.queue, self.stop_event, self.clock)
            for name, opener in openers.items()
        }
        self.status = Status({n: r.stats for n, r in self.readers.items()}, absent)
        self.sink = ObservedSink(log, self.status, self.reporter)
        try:
            self.pipeline = make_pipeline(self.sink)
        except ValueError:
            raise  # an invalid calibration: the caller reports it
        except Exception as exc:
            # a broken pipeline must not cost the survey: keep every byte for later re-processing
            self.sink.failed("pipeline_unavailable", exc)
            self.pipeline = RawOnly()
            self.record_raw = True
        self.status_interval_s = status_interval_s
        self.stop_signal = ""

    def request_stop(self) -> None:
        """Ask the loop to finish; safe from a signal handler."""
        self.stop_event.set()

    def _event(self, event: str, **fields: Any) -> None:
        self.reporter.event(event, **fields)
        self.sink.write("/daemon/event", self.clock.wall_ns(), DaemonEvent(event, fields))

    def post(self, topic: str, record: Record) -> None:
        """Log a record from another thread: written by the daemon's own loop, in order."""
        try:
            self.queue.put_nowait(Posted(topic, self.clock.wall_ns(), record))  # type: ignore[arg-type]
        except queue.Full:
            pass

    def _handle(self, item: Chunk | SourceEvent) -> None:
        if isinstance(item, Posted):
            if isinstance(item.record, DaemonEvent):
                self.reporter.event(item.record.event, **item.record.details)
            self.sink.write(item.topic, item.t_wall_ns, item.record)
            return
        if isinstance(item, Chunk):
            tap = self.taps.get(item.source)
            if tap is not None:
                try:
                    tap(item.data)
                except Exception as exc:
                    self.sink.failed(f"tap_{item.source}", exc)
            if self.record_raw:
                self.sink.write(f"/raw/{item.source}", item.t_wall_ns, raw_message(item))
            try:
                self.pipeline.feed(item.source, item.t_mono_ns, item.t_wall_ns, item.data)
            except Exception as exc:
                self.sink.failed(f"pipeline_{item.source}", exc)
            return
        fields = {"source": item.source}
        if item.reason:
            fields["reason"] = item.reason
        if item.detail:
            fields["detail"] = item.detail
        self.reporter.event(item.kind, **fields)
        self.sink.write("/daemon/event", item.t_wall_ns, DaemonEvent(item.kind, fields))
        if item.kind == "disconnected":
            try:
                self.pipeline.gap(item.source, item.t_wall_ns, item.reason)
            except Exception as exc:
                self.sink.failed("pipeline_gap", exc)

    def _status(self, final: bool = False) -> None:
        st = self.status
        try:
            st.pipeline_counters = dict(self.pipeline.counters())
        except Exception as exc:
            self.sink.failed("pipeline_counters", exc)
        if len(self.log.paths) != st.files:
            if st.files:
                self._event("rotated", file=str(self.log.path))
            st.files = len(self.log.paths)
        st.file = str(self.log.path)
        st.file_bytes = self.log.bytes_written
        st.update_rates()
        snap = st.snapshot()
        self.sink.write("/daemon/status", self.clock.wall_ns(), DaemonStatus(snap))
        self.reporter.status(st, final=final)

    def run(self) -> int:
        """Read, parse and log until ``request_stop``; then close everything cleanly."""
        self._event(
            "start",
            file=str(self.log.path),
            sources=sorted(self.readers),
            absent=self.status.absent,
            clock=getattr(self.clock, "name", "system"),
        )
        for reader in self.readers.values():
            reader.start()
        next_status = time.monotonic()
        try:
            while not self.stop_event.is_set():
                try:
                    item = self.queue.get(timeout=0.1)
                except queue.Empty:
                    item = None
                if item is not None:
                    self._handle(item)
                if time.monotonic() >= next_status:
                    next_status = time.monotonic() + self.status_interval_s
                    try:
                        self._status()
                    except Exception as exc:
                        self.sink.failed("status", exc)
                try:
                    self.log.tick()
                except Exception as exc:
                    self.sink.failed("log_flush", exc)
        finally:
            self._shutdown()
        return 0

    def _shutdown(self) -> None:
        self.stop_event.set()
        self.status.stopping = True
        if self.stop_signal:
            self._event("signal", signal=self.stop_signal)
        for reader in self.readers.values():
            if reader.is_alive():
                reader.join(timeout=2.0)
        while True:
            try:
                self._handle(self.queue.get_nowait())
            except queue.Empty:
                break
        for step in ("flush", "close"):
            try:
                getattr(self.pipeline, step)()
            except Exception as exc:
                self.sink.failed(f"pipeline_{step}", exc)
        self._status(final=True)
        self._event("stop", messages=self.log.messages, files=[str(p) for p in self.log.paths])
        self.log.close()
