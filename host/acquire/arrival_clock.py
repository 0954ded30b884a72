"""Clocks that stamp arriving bytes: the host's own, or the simulator's virtual clock (and its clock file,
which the simulator writes and the daemon reads)."""

from __future__ import annotations

import os
import struct
import threading
import time
from typing import Protocol

CLOCK_FORMAT = "<qqd"  # virtual_ns_at_anchor, host_monotonic_ns_at_anchor, speed
CLOCK_SIZE = struct.calcsize(CLOCK_FORMAT)  # 24 bytes


def write_anchor(path: str | os.PathLike[str], virtual_ns: int, mono_ns: int, speed: float) -> None:
    """Atomically (re)write the clock file: virtual time ``virtual_ns`` was current at host ``mono_ns``."""
    path = os.fspath(path)
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(struct.pack(CLOCK_FORMAT, int(virtual_ns), int(mono_ns), float(speed)))
    os.replace(tmp, path)


def read_anchor(path: str | os.PathLike[str]) -> tuple[int, int, float] | None:
    """The clock file's (virtual_ns, host monotonic ns, speed), or None while it is missing or short."""
    try:
        with open(path, "rb") as f:
            raw = f.read(CLOCK_SIZE)
    except OSError:
        return None
    if len(raw) < CLOCK_SIZE:
        return None
    return struct.unpack(CLOCK_FORMAT, raw)


class Clock(Protocol):
    """What the readers need: a monotonic and a wall clock, both in integer nanoseconds."""

    name: str
    speed: float  # virtual seconds per host second: 1, or the simulator's speed-up

    def monotonic_ns(self) -> int: ...

    def wall_ns(self) -> int: ...


class SystemClock:
    """The host's clocks: ``time.monotonic_ns`` and ``time.time_ns``."""

    name = "system"
    speed = 1.0

    def monotonic_ns(self) -> int:
        return time.monotonic_ns()

    def wall_ns(self) -> int:
        return time.time_ns()


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

    def _current_anchor(self) -> tuple[int, int, float]:
        host = time.monotonic_ns()
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


def parse_clock(spec: str) -> Clock:
    """``"system"`` or ``"sim:PATH"`` (the simulator's clock file) to a clock."""
    if spec in ("", "system"):
        return SystemClock()
    if spec.startswith("sim:") and len(spec) > 4:
        return SimClock(spec[4:])
    raise ValueError(f"unknown clock {spec!r}: expected 'system' or 'sim:PATH'")
