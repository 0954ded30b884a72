"""One reader thread per instrument: raw bytes stamped on arrival, reconnecting with backoff."""

from __future__ import annotations

import errno
import queue
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import serial
from forcemap.host.acquire.arrival_clock import CONNECTED, DISCONNECTED, Clock, SystemClock
from forcemap.host.acquire.transports import (  # noqa: F401 - part of this API
    MAX_READ,
    READ_TIMEOUT_S,
    Disconnected,
    SerialOpener,
    SerialTransport,
    Transport,
    UdpOpener,
    UdpTransport,
    parse_udp,
)

BACKOFF_START_S = 0.1
BACKOFF_MAX_S = 1.0
# how often a missing device path is checked for (a stat; cheap), so a replugged port is read at once
PRESENCE_POLL_S = 0.02
# a connection that lasted this long resets the backoff
STABLE_S = 2.0


@dataclass(frozen=True, slots=True)
class Chunk:
    """Bytes from one source, stamped when they arrived."""

    source: str
    t_mono_ns: int
    t_wall_ns: int
    data: bytes


@dataclass(frozen=True, slots=True)
class SourceEvent:
    """A change in a source's connection: ``kind`` is "connected" or "disconnected"."""

    source: str
    kind: str
    t_mono_ns: int
    t_wall_ns: int
    reason: str = ""
    detail: str = ""


def _classify(exc: BaseException) -> str:
    if isinstance(exc, Disconnected):
        return exc.reason
    if isinstance(exc, FileNotFoundError):
        return "port_missing"
    if isinstance(exc, PermissionError):
        return "permission"
    if isinstance(exc, OSError) and exc.errno == errno.EIO:
        return "eio"
    if isinstance(exc, ConnectionError | socket.timeout):
        return "connection"
    text = str(exc)
    if "[Errno 2]" in text or "No such file" in text:
        return "port_missing"
    if "exclusively lock" in text:
        return "port_busy"
    if "readiness to read but returned no data" in text:
        return "device_gone"
    if "Errno 5" in text:
        return "eio"
    if isinstance(exc, serial.SerialException):
        return "serial_error"
    return type(exc).__name__


def split_baud(port: str, default: int) -> tuple[str, int]:
    """``"PATH,BAUD"`` to (PATH, BAUD); a port without ``,BAUD`` gets ``default``."""
    path, comma, baud = port.rpartition(",")
    if comma and baud.isdigit():
        return path, int(baud)
    return port, default


def port_opener(port: str, baudrate: int = 115200) -> Callable[[], Transport]:
    """Opener for a PORT: anything pyserial opens (a path or a URL)."""
    return SerialOpener(port, baudrate)


def _network_opener(conn: str) -> Callable[[], Transport] | None:
    """``udp:``/``udpin:`` (listen) or ``tcp:HOST:PORT`` (connect); None for anything else."""
    scheme, _, rest = conn.partition(":")
    if scheme in ("udp", "udpin"):
        return UdpOpener(*parse_udp(conn))
    if scheme == "tcp" and rest:
        return SerialOpener(f"socket://{rest}")
    return None


def nmea_opener(port: str, baudrate: int = 4800) -> Callable[[], Transport]:
    """Opener for an NMEA 0183 instrument: a serial PORT[,BAUD], a pyserial URL (``socket://`` for
    a TCP multiplexer), ``udp:[HOST:]PORT`` (a UDP broadcast, usually port 10110) or ``tcp:HOST:PORT``.
    """
    return _network_opener(port) or SerialOpener(*split_baud(port, baudrate))


def mavlink_opener(conn: str) -> Callable[[], Transport]:
    """Opener for a pymavlink-style connection string, read as raw bytes.

    ``/dev/ttyACM0,57600`` (serial with baud), ``udp:HOST:PORT`` or ``udpin:HOST:PORT`` (listen),
    ``tcp:HOST:PORT`` (connect), or anything pyserial opens.
    """
    opener = _network_opener(conn)
    if opener is not None:
        return opener
    scheme, _, rest = conn.partition(":")
    if scheme and rest and "://" not in conn and "/" not in scheme:
        raise ValueError(
            f"unsupported MAVLink connection {conn!r}: use a serial path with baud "
            "(/dev/ttyACM0,57600), udp:HOST:PORT, udpin:HOST:PORT or tcp:HOST:PORT"
        )
    return SerialOpener(*split_baud(conn, 115200))


@dataclass
class ReaderStats:
    """Counters one reader keeps; read by the status display from the main thread."""

    connected: bool = False
    bytes: int = 0
    chunks: int = 0
    connects: int = 0
    disconnects: int = 0
    errors: dict[str, int] = field(default_factory=dict)
    last_error: str = ""
    queue_drops: int = 0


class Reader(threading.Thread):
    """Reads one source until ``stop`` is set; puts Chunks and SourceEvents on ``out``.

    Opening or reading failures never end the thread: it closes what it has, reports one
    "disconnected" event per outage, retries with backoff (0.1 s doubling to 1 s) and reports
    "connected" when bytes can flow again.
    """

    def __init__(
        self,
        name: str,
        opener: Callable[[], Transport],
        out: queue.Queue,
        stop: threading.Event,
        clock: Clock | None = None,
        *,
        backoff_start_s: float = BACKOFF_START_S,
        backoff_max_s: float = BACKOFF_MAX_S,
    ):
        super().__init__(name=f"reader-{name}", daemon=True)
        self.source = name
        self._opener = opener
        self._out = out
        self._stop_event = stop
        self._clock = clock or SystemClock()
        self._backoff_start = backoff_start_s
        self._backoff_max = backoff_max_s
        self.stats = ReaderStats()
        self._down = True
        self._first = True
        self._transport: Transport | None = None  # while open: ``write`` sends through it

    def write(self, data: bytes) -> bool:
        """Send bytes out of this source's port (a ground station's uplink); False if it is not open
        or cannot be written."""
        t = self._transport
        try:
            if t is None or not hasattr(t, "write"):
                return False
            t.write(data)  # type: ignore[attr-defined]
            return True
        except Exception:
            return False

    def _emit(self, item: Chunk | SourceEvent) -> None:
        try:
            self._out.put(item, timeout=1.0)
        except queue.Full:
            self.stats.queue_drops += 1

    def _event(self, kind: str, reason: str = "", detail: str = "") -> None:
        self._emit(
            SourceEvent(
                self.source,
                kind,
                self._clock.monotonic_ns(),
                self._clock.wall_ns(),
                reason,
                detail,
            )
        )

    def _failed(self, exc: BaseException) -> None:
        reason = _classify(exc)
        self.stats.errors[reason] = self.stats.errors.get(reason, 0) + 1
        self.stats.last_error = f"{reason}: {exc}"
        if not self._down or self._first:
            self._down = True
            self._first = False
            self.stats.connected = False
            self.stats.disconnects += 1
            self._event("disconnected", reason, str(exc))
            self._clock.note(self.source, DISCONNECTED)

    def run(self) -> None:
        while not self._stop_event.is_set():
            try:
                self._run()
            except Exception as exc:  # a bug here must not silence the source for the whole run
                self.stats.errors["internal"] = self.stats.errors.get("internal", 0) + 1
                self.stats.last_error = f"internal: {exc!r}"
                self._stop_event.wait(self._backoff_max)
        self.stats.connected = False

    def _run(self) -> None:
        delay = self._backoff_start
        while not self._stop_event.is_set():
            try:
                transport = self._opener()
            except Exception as exc:
                self._failed(exc)
                self._wait_retry(delay)
                delay = min(delay * 2, self._backoff_max)
                continue
            self._down = False
            self._first = False
            self.stats.connected = True
            self.stats.connects += 1
            self._event("connected")
            self._clock.note(self.source, CONNECTED)
            opened = time.monotonic()
            failure: Exception | None = None
            self._transport = transport
            try:
                self._pump(transport)
            except Exception as exc:
                failure = exc
            finally:
                self._transport = None
                transport.close()
            if failure is not None:
                self._failed(failure)
                # a port that fails right after opening backs off like one that will not open
                stable = time.monotonic() - opened >= STABLE_S
                delay = self._backoff_start if stable else min(delay * 2, self._backoff_max)
                self._wait_retry(delay)
        self.stats.connected = False

    def _wait_retry(self, delay: float) -> None:
        """Back off before the next open; a missing device path is watched so its return is quick."""
        present = getattr(self._opener, "present", None)
        if present is None or present():
            self._stop_event.wait(delay)
            return
        deadline = time.monotonic() + delay
        while not self._stop_event.wait(PRESENCE_POLL_S):
            if present() or time.monotonic() >= deadline:
                return

    def _pump(self, transport: Transport) -> None:
        clock = self._clock
        stats = self.stats
        while not self._stop_event.is_set():
            data = transport.read()
            if not data:
                continue
            t_mono = clock.monotonic_ns()
            t_wall = clock.wall_ns()
            stats.bytes += len(data)
            stats.chunks += 1
            self._emit(Chunk(self.source, t_mono, t_wall, bytes(data)))
            clock.note(self.source, str(len(data)))  # queued: a lockstep simulator may go on
