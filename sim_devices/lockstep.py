"""The simulator's clock drives the daemon: every chunk is stamped at its virtual send time, whatever the load.

`run_live` paces the simulator to real time x speed and the daemon stamps bytes when they arrive; on a
busy machine they arrive late, the simulator falls behind and re-anchors, and the same seed gives
another log. Here (`forcemap sim --ports DIR --lockstep SOURCES`, what `forcemap demo` runs) the
clock file stands still (speed 0) at the send time of the chunk about to be written; the daemon's
readers (`host/acquire/sources.py`) stamp what they read with it, queue it, and say so on the FIFO
``DIR/clock.ack`` (`host/acquire/arrival_clock.py`); only then does the simulator write the next
chunk. So every byte the daemon reads carries its send time and reaches its queue in the simulator's
order. A cable pulled or plugged waits for the reader to see it. ``speed`` only caps the pace (for a
viewer of `--live`); a slow machine makes the run slower, never different.

A reader that does not answer within ``patience_s`` of host time (no daemon, or one stalled that long)
is not waited for again: its port goes on as without lockstep (counted in ``Lockstep.timeouts``; a run
with timeouts is no longer guaranteed to repeat).
"""

from __future__ import annotations

import os
import select
import threading
import time
from collections.abc import Callable, Iterable

from forcemap.host.acquire.arrival_clock import (
    CONNECTED,
    DISCONNECTED,
    LOCKSTEP,
    AnchorWriter,
    ack_path,
)

from .engine import Simulation
from .ports import PortSet

PATIENCE_S = 30.0  # host seconds a reader may take to answer (a stalled daemon; then we go on)


class Lockstep:
    """The simulator's side of the handshake: the clock it sets, the FIFO it reads."""

    def __init__(self, ports: PortSet, sources: Iterable[str], patience_s: float = PATIENCE_S):
        self.ports, self.sources, self.patience_s = ports, set(sources), patience_s
        self.clock = AnchorWriter(ports.clock_path)
        self.fifo = ack_path(ports.clock_path)
        if os.path.lexists(self.fifo):
            os.unlink(self.fifo)
        os.mkfifo(self.fifo)
        # non-blocking: opening waits for no writer, reading never hangs the simulator
        self.fd = os.open(self.fifo, os.O_RDONLY | os.O_NONBLOCK)
        self._buf = b""
        self.acked = dict.fromkeys(self.sources, 0)
        self.sent = dict.fromkeys(self.sources, 0)
        self.news: dict[str, list[str]] = {s: [] for s in self.sources}
        self.timeouts = 0
        self.chunks = 0
        self.waited_s = 0.0

    def set_clock(self, t_ns: int) -> None:
        self.clock.write(t_ns, time.monotonic_ns(), LOCKSTEP)

    def _read(self, timeout: float) -> None:
        ready, _, _ = select.select([self.fd], [], [], timeout)
        if not ready:
            return
        try:
            data = os.read(self.fd, 65536)
        except BlockingIOError:
            return
        if (
            not data
        ):  # no writer (the daemon closed its end): wait a little, as select returns at once
            time.sleep(min(timeout, 0.01))
            return
        self._buf += data
        *lines, self._buf = self._buf.split(b"\n")
        for line in lines:
            source, _, what = line.decode("ascii", "replace").partition(" ")
            if source not in self.acked:
                continue
            if what.isdigit():
                self.acked[source] += int(what)
            else:
                self.news[source].append(what)

    def _until(self, done: Callable[[], bool]) -> bool:
        start = time.monotonic()
        deadline = start + self.patience_s
        while not done():
            left = deadline - time.monotonic()
            if left <= 0:
                self.timeouts += 1
                return False
            self._read(min(left, 0.5))
        self.waited_s += time.monotonic() - start
        return True

    def wait_news(self, source: str, what: str) -> bool:
        """Wait until ``source``'s reader says ``what`` (connected, disconnected)."""

        def seen() -> bool:
            if what in self.news[source]:
                self.news[source].remove(what)
                return True
            return False

        if source not in self.sources:
            return False
        if self._until(seen):
            return True
        self.sources.discard(source)  # not answering: not waited for again
        return False

    def write(self, source: str, t_ns: int, data: bytes) -> None:
        """Set the clock to the chunk's send time, write it, and wait until the daemon has queued it."""
        if source not in self.sources:  # a port nobody reads here: its bytes go as before
            self.ports.write(source, data)
            return
        self.set_clock(t_ns)
        before = self.ports.bytes_written[source]
        # the reader has acknowledged every earlier byte, so the port holds none: the bridge's count
        # of unread bytes is exact without the 1-ms settle (a spin, 36,012 chunks in the demo)
        self.ports.write(source, data, settle=False)
        self.sent[source] += self.ports.bytes_written[source] - before
        self.chunks += 1
        if not self._until(lambda: self.acked[source] >= self.sent[source]):
            self.sources.discard(source)  # not answering: its port goes on without lockstep

    def event(self, kind: str, source: str, t_ns: int) -> None:
        """A cable pulled or plugged, in time order with the bytes; the reader must see it first."""
        self.set_clock(t_ns)
        self.ports.event(kind, source, t_ns)
        if source in self.sources and kind in ("unplug", "plug"):
            self.wait_news(source, DISCONNECTED if kind == "unplug" else CONNECTED)
            self.acked[source] = self.sent[source]  # bytes left in a pulled port are lost

    def close(self) -> None:
        self.clock.close()
        os.close(self.fd)
        if os.path.lexists(self.fifo):
            os.unlink(self.fifo)


def run_lockstep(
    sim_factory: Callable[..., Simulation],
    ports: PortSet,
    duration_s: float,
    sources: Iterable[str],
    speed: float | None = None,
    stop: threading.Event | None = None,
    on_progress: Callable[[float, float], None] | None = None,
) -> tuple[Simulation, Lockstep]:
    """Drive a simulation in lockstep with a daemon reading ``sources`` (`--clock sim:DIR/clock`).

    The daemon may start first (it waits for the clock file); the run starts once every source's
    reader has connected. ``speed``: at most this many virtual seconds per host second."""
    lock = Lockstep(ports, sources)
    sim = sim_factory(bridge_writable=ports.bridge_writable, events=lock.event)
    lock.set_clock(sim.t0_ns)
    for s in sorted(lock.sources):
        lock.wait_news(s, CONNECTED)
    sim.start(duration_s, lock.write)
    start = time.monotonic()
    next_report = 0.0
    try:
        while sim.t < duration_s and not (stop is not None and stop.is_set()):
            uplink = ports.read("mavlink")
            if uplink:
                sim.uplink(uplink)
            sim.advance(min(sim.t + 0.5, duration_s))
            if speed:
                ahead = sim.t / speed - (time.monotonic() - start)
                if ahead > 0:
                    time.sleep(ahead)
            if on_progress is not None and sim.t >= next_report:
                next_report = sim.t + 10.0
                on_progress(sim.t, duration_s)
    finally:
        sim.finish()
        lock.close()
    return sim, lock
