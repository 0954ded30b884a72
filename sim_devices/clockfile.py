"""The clock file that lets the daemon stamp arrivals with the simulator's virtual time at any speed."""

from __future__ import annotations

import os
import struct
import time

FORMAT = "<qqd"  # virtual_ns_at_anchor, host_monotonic_ns_at_anchor, speed
SIZE = struct.calcsize(FORMAT)  # 24 bytes


def write_anchor(path: str | os.PathLike[str], virtual_ns: int, mono_ns: int, speed: float) -> None:
    """Atomically (re)write the anchor: virtual time ``virtual_ns`` was current at host ``mono_ns``."""
    path = os.fspath(path)
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(struct.pack(FORMAT, int(virtual_ns), int(mono_ns), float(speed)))
    os.replace(tmp, path)


def read_anchor(path: str | os.PathLike[str]) -> tuple[int, int, float]:
    with open(path, "rb") as f:
        return struct.unpack(FORMAT, f.read(SIZE))


class SimClock:
    """Virtual UNIX time in ns: anchor virtual time + (host monotonic now - anchor) x speed."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = os.fspath(path)

    def now_ns(self) -> int:
        v0, m0, speed = read_anchor(self.path)
        return v0 + int((time.monotonic_ns() - m0) * speed)
