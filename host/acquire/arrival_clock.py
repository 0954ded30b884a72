"""Clocks that stamp arriving bytes: the host's own, or the simulator's virtual clock (and its clock file,
which the simulator writes and the daemon reads).

In lockstep (`forcemap sim --lockstep`, what `forcemap demo` runs) the simulator's clock drives the
daemon: the clock file's speed is 0, so the clock stands at the file's virtual time, which the
simulator sets to each chunk's send time before writing it; the daemon's readers tell it, through the
FIFO ``<clock>.ack``, each chunk they have stamped and queued (and each connect and disconnect), and
the simulator writes nothing more until they have. Every byte is then stamped with its virtual send
time and queued in the simulator's order, however busy the machine: the same seed gives the same log.
"""

from __future__ import annotations

import os
import struct
import threading
import time
from typing import Protocol

CLOCK_FORMAT = "<qqd"  # virtual_ns_at_anchor, host_monotonic_ns_at_anchor, speed
CLOCK_SIZE = struct.calcsize(CLOCK_FORMAT)  # 24 bytes
LOCKSTEP = 0.0  # the speed that says: the clock stands where the simulator put it
CONNECTED, DISCONNECTED = "+", "-"  # what a reader says on the ack FIFO besides byte counts


def ack_path(clock_path: str | os.PathLike[str]) -> str:
    """The FIFO on which a lockstep daemon acknowledges what it has read."""
    return os.fspath(clock_path) + ".ack"


def write_anchor(path: str | os.PathLike[str], virtual_ns: int, mono_ns: int, speed: float) -> None:
    """Atomically (re)write the clock file: virtual time ``virtual_ns`` was current at host ``mono_ns``."""
    path = os.fspath(path)
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(struct.pack(CLOCK_FORMAT, int(virtual_ns), int(mono_ns), float(speed)))
    os.replace(tmp, path)


class AnchorWriter:
    """Rewrites the clock file in place (a lockstep simulator moves it at every chunk: a new file and a
    rename each time would cost a millisecond). The first anchor still appears whole (`write_anchor`)."""

    def __init__(self, path: str | os.PathLike[str]):
        self.path = os.fspath(path)
        self._fd: int | None = None

    def write(self, virtual_ns: int, mono_ns: int, speed: float) -> None:
        if self._fd is None:
            write_anchor(self.path, virtual_ns, mono_ns, speed)
            self._fd = os.open(self.path, os.O_WRONLY)
            return
        os.pwrite(self._fd, struct.pack(CLOCK_FORMAT, int(virtual_ns), int(mono_ns), speed), 0)

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def read_anchor(
    path: str | os.PathLike[str], fd: int | None = None
) -> tuple[int, int, float] | None:
    """The clock file's (virtual_ns, host monotonic ns, speed), or None while it is missing or short;
    from ``fd`` (the file open already) when given.

    Read until two reads agree, so an anchor rewritten in place (`AnchorWriter`) is never read half old,
    half new."""
    previous = None
    for _ in range(5):
        try:
            if fd is not None:
                raw = os.pread(fd, CLOCK_SIZE, 0)
            else:
                with open(path, "rb") as f:
                    raw = f.read(CLOCK_SIZE)
        except OSError:
            return None
        if len(raw) < CLOCK_SIZE:
            return None
        if raw == previous:
            break
        previous = raw
    return struct.unpack(CLOCK_FORMAT, raw)


class Clock(Protocol):
    """What the readers need: a monotonic and a wall clock, both in integer nanoseconds."""

    name: str
    speed: float  # virtual seconds per host second: 1, or the simulator's speed-up

    def monotonic_ns(self) -> int: ...

    def wall_ns(self) -> int: ...

    def note(self, source: str, what: str) -> None:
        """A reader's news: bytes stamped and queued (their count), `+` connected, `-` disconnected."""


class SystemClock:
    """The host's clocks: ``time.monotonic_ns`` and ``time.time_ns``."""

    name = "system"
    speed = 1.0

    def monotonic_ns(self) -> int:
        return time.monotonic_ns()

    def wall_ns(self) -> int:
        return time.time_ns()

    def note(self, source: str, what: str) -> None:
        pass


class SimClock:
    """The simulator's virtual UNIX clock, read from its clock file; both clocks return it.

    The file holds ``i64 virtual_ns_at_anchor, i64 host_monotonic_ns_at_anchor, f64 speed``
    (little-endian). It is re-read at most every ``reread_s`` so a re-anchor (pause, speed change)
    is picked up. Before the file exists the clock waits for it up to ``wait_s`` and then raises.
    """

    def __init__(
        self, path: str | os.PathLike[str], *, wait_s: float = 30.0, reread_s: float = 0.02
    ):
        self.path = os.fspath(path)
        self.name = f"sim:{self.path}"
        self._wait_s = wait_s
        self._reread_ns = int(reread_s * 1e9)
        self._anchor: tuple[int, int, float] | None = None
        self._read_at = 0
        self._last = 0
        self._lock = threading.Lock()
        self._ack: int | None = None  # the lockstep FIFO's write end, once open
        self._fd: int | None = None  # in lockstep: the clock file, open (`_read_locked_step`)
        self._fd_at = 0

    def _read_locked_step(self, host: int) -> tuple[int, int, float] | None:
        """In lockstep the anchor moves at every chunk, rewritten in place: read through a descriptor
        kept open (two preads, where opening the file each time took about ten system calls, each a
        hand-over of the GIL that a busy machine makes slow: issue 58), opened again every
        ``reread_s`` so a clock file replaced (a new simulator) is followed."""
        if self._fd is not None and host - self._fd_at >= self._reread_ns:
            os.close(self._fd)
            self._fd = None
        if self._fd is None:
            try:
                self._fd = os.open(self.path, os.O_RDONLY)
            except OSError:
                return None
            self._fd_at = host
        return read_anchor(self.path, self._fd)

    def _current_anchor(self) -> tuple[int, int, float]:
        host = time.monotonic_ns()
        lockstep = self._anchor is not None and self._anchor[2] == LOCKSTEP
        if lockstep:
            anchor = self._read_locked_step(host)
            if anchor is not None:
                self._anchor = anchor
            self._read_at = host
            return self._anchor
        if self._fd is not None:  # lockstep ended: the simulator re-anchors by replacing the file
            os.close(self._fd)
            self._fd = None
        if self._anchor is None or host - self._read_at >= self._reread_ns:
            anchor = read_anchor(self.path)
            deadline = time.monotonic() + self._wait_s
            while anchor is None and self._anchor is None:
                if time.monotonic() > deadline:
                    raise FileNotFoundError(f"simulator clock file {self.path} did not appear")
                time.sleep(0.05)
                anchor = read_anchor(self.path)
            if anchor is not None:
                self._anchor = anchor
            self._read_at = host
        assert self._anchor is not None
        return self._anchor

    @property
    def speed(self) -> float:
        with self._lock:
            return self._current_anchor()[2]

    def now_ns(self) -> int:
        with self._lock:
            virtual0, host0, speed = self._current_anchor()
            now = virtual0 + int((time.monotonic_ns() - host0) * speed)
            # a re-anchor must not make the virtual clock step backwards
            self._last = max(self._last, now)
            return self._last

    def monotonic_ns(self) -> int:
        return self.now_ns()

    def wall_ns(self) -> int:
        return self.now_ns()

    def note(self, source: str, what: str) -> None:
        """Tell a lockstep simulator (one line on its FIFO); nothing when it is not listening."""
        with self._lock:
            if self._anchor is None or self._anchor[2] != LOCKSTEP:
                return
            if self._ack is None:
                try:
                    self._ack = os.open(ack_path(self.path), os.O_WRONLY | os.O_NONBLOCK)
                except OSError:  # no FIFO, or nobody reads it: the simulator is not in lockstep
                    return
            try:
                os.write(self._ack, f"{source} {what}\n".encode())  # < PIPE_BUF: one write
            except BlockingIOError:  # the simulator stopped reading: it has given up waiting
                pass
            except OSError:
                os.close(self._ack)
                self._ack = None


def parse_clock(spec: str) -> Clock:
    """``"system"`` or ``"sim:PATH"`` (the simulator's clock file) to a clock."""
    if spec in ("", "system"):
        return SystemClock()
    if spec.startswith("sim:") and len(spec) > 4:
        return SimClock(spec[4:])
    raise ValueError(f"unknown clock {spec!r}: expected 'system' or 'sim:PATH'")
