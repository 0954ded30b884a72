"""Crash-safe MCAP logging with JSON channels, rotation, and a reader for complete or truncated files."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any, BinaryIO, NamedTuple

from forcemap.host.log.messages import Record, as_json, record_type
from mcap.records import Attachment, Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

PROFILE = ""
LIBRARY = "forcemap"
MCAP_MAGIC = b"\x89MCAP0\r\n"
CHUNK_SIZE = 64 * 1024
FLUSH_INTERVAL_S = 0.5
FSYNC_INTERVAL_S = 5.0
ROTATE_BYTES = 256 * 1024 * 1024
ROTATE_SECONDS = 3600.0


def schema_for(
    topic: str, message: Record | dict[str, Any] | None = None
) -> tuple[str, dict[str, Any]]:
    """(schema name, JSON schema): the record's own, else the topic's record type, else permissive."""
    rtype = type(message) if isinstance(message, Record) else record_type(topic)
    if rtype is not None:
        return rtype.NAME, rtype.json_schema()
    name = "forcemap." + (topic.strip("/").replace("/", ".") or "message")
    return name, {"title": name, "type": "object"}


def _json_default(value: Any) -> Any:
    if isinstance(value, bytes | bytearray | memoryview):
        return bytes(value).hex()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.asdict(value)
    if isinstance(value, set | frozenset):
        return sorted(value)
    for attr in ("tolist", "item"):  # numpy arrays and scalars without importing numpy
        if hasattr(value, attr):
            return getattr(value, attr)()
    return str(value)


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


# json.dumps with these arguments, made once (dumps builds an encoder per call: a tenth of a message's cost)
_COMPACT = json.JSONEncoder(separators=(",", ":"), allow_nan=False, default=_json_default)


def encode_json(message: dict[str, Any]) -> bytes:
    """Compact JSON; NaN and infinities become null because JSON has no such numbers."""
    try:
        text = _COMPACT.encode(message)
    except ValueError:
        plain = json.loads(json.dumps(message, default=_json_default))
        text = json.dumps(_finite(plain), separators=(",", ":"), allow_nan=False)
    return text.encode()


class McapLog:
    """The daemon's sink: JSON-schema channels in MCAP files under ``out_dir``, one per run.

    A new file starts when the current one reaches ``rotate_bytes`` or ``rotate_seconds`` (host
    time); each finished file has its summary and repeats every metadata record. Chunks are small
    and flushed to the OS every ``flush_interval_s`` (on write, or from ``tick()``), and fsynced
    every ``fsync_interval_s``, so a killed process loses at most the last flush interval.
    ``clock`` (seconds, monotonic) times flushes and rotation; tests pass a virtual one.
    """

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        *,
        rotate_bytes: int = ROTATE_BYTES,
        rotate_seconds: float = ROTATE_SECONDS,
        prefix: str = "run",
        chunk_size: int = CHUNK_SIZE,
        flush_interval_s: float = FLUSH_INTERVAL_S,
        fsync_interval_s: float = FSYNC_INTERVAL_S,
        compression: CompressionType = CompressionType.ZSTD,
        first_path: str | os.PathLike[str] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ):
        self._clock = clock
        self.out_dir = Path(out_dir)
        self._first_path = Path(first_path) if first_path is not None else None
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.rotate_bytes = rotate_bytes
        self.rotate_seconds = rotate_seconds
        self.prefix = prefix
        self.chunk_size = chunk_size
        self.flush_interval_s = flush_interval_s
        self.fsync_interval_s = fsync_interval_s
        self.compression = compression
        self.paths: list[Path] = []
        self.messages = 0
        self.topic_counts: dict[str, int] = {}
        self._finished_bytes = 0
        self._metadata: dict[str, dict[str, str]] = {}
        self._schemas: dict[str, tuple[str, dict[str, Any]]] = {}
        self._channels: dict[str, int] = {}
        self._lock = threading.RLock()
        self._file: BinaryIO | None = None
        self._writer: Writer | None = None
        self._closed = False
        # called with (topic, log_time_ns, encoded JSON, message) after every write; must not block
        # or raise (the live view's bounded queue: forcemap.host.live.tee.LiveTee.offer)
        self.tee: Callable[[str, int, bytes, Record | dict[str, Any]], None] | None = None
        self._open()

    @property
    def path(self) -> Path:
        """The file being written now (the last one after ``close``)."""
        return self.paths[-1]

    @property
    def bytes_written(self) -> int:
        """Bytes in all files of this run so far."""
        f = self._file
        return self._finished_bytes + (f.tell() if f is not None and not f.closed else 0)

    def _new_path(self) -> Path:
        if self._first_path is not None:  # a file name the caller chose (e.g. a temporary one)
            path, self._first_path = self._first_path, None
            return path
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        for n in range(1000):
            suffix = f"-{n}" if n else ""
            path = self.out_dir / f"{self.prefix}-{stamp}{suffix}.mcap"
            try:
                fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                continue
            os.close(fd)
            return path
        raise FileExistsError(f"no free file name for {self.prefix}-{stamp} in {self.out_dir}")

    def _open(self) -> None:
        path = self._new_path()
        self._file = open(path, "wb")  # noqa: SIM115 - kept open for the file's life
        self._writer = Writer(self._file, chunk_size=self.chunk_size, compression=self.compression)
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._channels = {}
        self._schema_ids: dict[str, int] = {}
        for name, data in self._metadata.items():
            self._writer.add_metadata(name, data)
        self.paths.append(path)
        self._opened_at = self._clock()
        self._flush(fsync=True)

    def _flush(self, fsync: bool) -> None:
        assert self._writer is not None and self._file is not None
        self._writer.flush()
        now = self._clock()
        self._flushed_at = now
        if fsync:
            os.fsync(self._file.fileno())
            self._synced_at = now

    def _channel(self, topic: str, message: Record | dict[str, Any]) -> int:
        assert self._writer is not None
        channel_id = self._channels.get(topic)
        if channel_id is not None:
            return channel_id
        if topic not in self._schemas:
            self._schemas[topic] = schema_for(topic, message)
        name, schema = self._schemas[topic]
        schema_id = self._schema_ids.get(name)
        if schema_id is None:
            schema_id = self._writer.register_schema(
                name=name, encoding="jsonschema", data=json.dumps(schema).encode()
            )
            self._schema_ids[name] = schema_id
        channel_id = self._writer.register_channel(
            topic=topic, message_encoding="json", schema_id=schema_id
        )
        self._channels[topic] = channel_id
        return channel_id

    def write(self, topic: str, log_time_ns: int, message: Record | dict[str, Any]) -> None:
        """Log one message on ``topic`` at ``log_time_ns`` (UNIX ns); a record brings its schema."""
        data = encode_json(as_json(message))
        with self._lock:
            if self._closed:
                raise ValueError("McapLog is closed")
            assert self._writer is not None
            self._writer.add_message(
                self._channel(topic, message), int(log_time_ns), data, int(log_time_ns)
            )
            self.messages += 1
            self.topic_counts[topic] = self.topic_counts.get(topic, 0) + 1
            self._maintain()
        if self.tee is not None:
            self.tee(topic, int(log_time_ns), data, message)

    def metadata(self, name: str, data: dict[str, str]) -> None:
        """Record a metadata record now and at the start of every later file of this run."""
        clean = {str(k): str(v) for k, v in data.items()}
        with self._lock:
            if self._closed:
                raise ValueError("McapLog is closed")
            assert self._writer is not None
            self._metadata[name] = clean
            self._writer.add_metadata(name, clean)
            self._flush(fsync=False)

    def tick(self) -> None:
        """Flush, fsync or rotate if due; call this regularly even when nothing is written."""
        with self._lock:
            if not self._closed:
                self._maintain()

    def _maintain(self) -> None:
        now = self._clock()
        if now - self._flushed_at < self.flush_interval_s:
            return
        self._flush(fsync=now - self._synced_at >= self.fsync_interval_s)
        assert self._file is not None
        # checked at flush time only: a file ends up to one flush interval past the limits
        if self._file.tell() >= self.rotate_bytes or now - self._opened_at >= self.rotate_seconds:
            self.rotate()

    def flush(self, fsync: bool = True) -> None:
        """Write everything buffered to the file now."""
        with self._lock:
            if not self._closed:
                self._flush(fsync=fsync)

    def _finish(self) -> None:
        assert self._writer is not None and self._file is not None
        self._writer.finish()
        self._file.flush()
        os.fsync(self._file.fileno())
        self._finished_bytes += self._file.tell()
        self._file.close()
        self._writer = None
        self._file = None

    def rotate(self) -> None:
        """Finish the current file (with its summary) and continue in a new one."""
        with self._lock:
            if self._closed:
                return
            self._finish()
            self._open()

    def close(self) -> None:
        """Finish the current file with its summary. Safe to call twice."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._finish()

    def __enter__(self) -> McapLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class LogMessage(NamedTuple):
    """One decoded message: unpacks as ``topic, log_time_ns, message``."""

    topic: str
    log_time_ns: int
    message: dict[str, Any]


@dataclasses.dataclass
class FileScan:
    """What reading a whole file found; ``error`` is why reading stopped early (truncation)."""

    path: Path
    complete: bool = False
    truncated: bool = False
    error: str = ""
    schemas: dict[int, Schema] = dataclasses.field(default_factory=dict)
    channels: dict[int, Channel] = dataclasses.field(default_factory=dict)
    metadata: list[Metadata] = dataclasses.field(default_factory=list)
    attachments: list[Attachment] = dataclasses.field(default_factory=list)


def has_footer(path: str | os.PathLike[str]) -> bool:
    """True if the file ends with the MCAP magic, i.e. it was finished."""
    with open(path, "rb") as f:
        f.seek(0, os.SEEK_END)
        if f.tell() < 2 * len(MCAP_MAGIC):
            return False
        f.seek(-len(MCAP_MAGIC), os.SEEK_END)
        return f.read() == MCAP_MAGIC


def iter_records(path: str | os.PathLike[str], scan: FileScan | None = None) -> Iterator[Any]:
    """Every record in file order, stopping quietly at a truncation (noted in ``scan``)."""
    scan = scan if scan is not None else FileScan(Path(path))
    scan.complete = has_footer(path)
    with open(path, "rb") as f:
        # the non-seeking path: it needs no summary, so it reads killed and truncated files
        records = StreamReader(f).records
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except Exception as exc:  # EndOfFile, struct.error, bad chunk: the tail is lost
                scan.truncated = True
                scan.error = f"{type(exc).__name__}: {exc}"
                return
            if isinstance(record, Schema):
                scan.schemas[record.id] = record
            elif isinstance(record, Channel):
                scan.channels[record.id] = record
            elif isinstance(record, Metadata):
                scan.metadata.append(record)
            elif isinstance(record, Attachment):
                scan.attachments.append(record)
            yield record


def iter_metadata(path: str | os.PathLike[str]) -> Iterator[tuple[str, dict[str, str]]]:
    """(name, data) of every metadata record of a file, in file order: from a complete file's metadata
    index without reading a message, else (no summary, or an index short of the summary's count) by
    reading the file through."""
    indexed = _indexed_metadata(path) if has_footer(path) else None
    if indexed is not None:
        yield from indexed
        return
    for record in iter_records(path):
        if isinstance(record, Metadata):
            yield record.name, dict(record.metadata)


def _indexed_metadata(path: str | os.PathLike[str]) -> list[tuple[str, dict[str, str]]] | None:
    """The metadata records a complete file's summary indexes, or None when it does not index them all."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            stats = summary.statistics if summary is not None else None
            if stats is None or stats.metadata_count != len(summary.metadata_indexes):
                return None
            return [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
    except Exception:  # a summary the reader cannot use: the caller reads the records themselves
        return None


def read_messages(
    paths: str | os.PathLike[str] | Iterable[str | os.PathLike[str]],
    topics: Iterable[str] | str | None = None,
    *,
    scan: FileScan | None = None,
    accept: Callable[[str, bytes], bool] | None = None,
) -> Iterator[LogMessage]:
    """Decoded JSON messages from complete or truncated files, in file order.

    A truncated file yields every message of its complete chunks and then stops without raising.
    Messages that are not valid JSON are skipped. ``accept(topic, data)``: decode only the
    messages it accepts (a cheap test on the bytes spares decoding the rest).
    """
    if isinstance(paths, str | os.PathLike):
        paths = [paths]
    wanted = {topics} if isinstance(topics, str) else (set(topics) if topics else None)
    for path in paths:
        file_scan = scan if scan is not None else FileScan(Path(path))
        for record in iter_records(path, file_scan):
            if not isinstance(record, Message):
                continue
            channel = file_scan.channels.get(record.channel_id)
            if channel is None or (wanted is not None and channel.topic not in wanted):
                continue
            if accept is not None and not accept(channel.topic, record.data):
                continue
            try:
                message = json.loads(record.data)
            except ValueError:
                continue
            yield LogMessage(channel.topic, record.log_time, message)
