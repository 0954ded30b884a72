"""Live transport: one pty per instrument behind stable symlinks, paced to real time x speed."""

from __future__ import annotations

import fcntl
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

from forcemap.host.acquire.arrival_clock import write_anchor

from .engine import Simulation
from .usb_cdc import HOST_BUFFER, UsbCdc

SOURCES = ("bridge", "depth", "mavlink", "nmea")


class PortSet:
    """The ports directory: ``bridge``, ``depth`` and ``mavlink`` symlinks to ptys, plus ``clock``."""

    def __init__(self, ports_dir: str | os.PathLike[str]) -> None:
        self.dir = Path(ports_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.ports: dict[str, UsbCdc | None] = {s: self._open(s) for s in SOURCES}
        self.bytes_written = dict.fromkeys(SOURCES, 0)
        self.dropped = dict.fromkeys(SOURCES, 0)
        self.reanchors = 0  # times the clock file was re-anchored because the simulator fell behind

    def _open(self, source: str) -> UsbCdc:
        # the bridge is USB-CDC (it drops what the host does not read); the others are UARTs
        port = UsbCdc(self.path(source), host_buffer=HOST_BUFFER if source == "bridge" else None)
        # FIONREAD on a pty stops at the line discipline's 4095 bytes, so a port nobody reads never
        # looks full and a blocking write would hang the simulator once the kernel buffer fills
        flags = fcntl.fcntl(port.master, fcntl.F_GETFL)
        fcntl.fcntl(port.master, fcntl.F_SETFL, flags | os.O_NONBLOCK)
        return port

    def path(self, source: str) -> str:
        return str(self.dir / source)

    @property
    def clock_path(self) -> str:
        return str(self.dir / "clock")

    def write(self, source: str, data: bytes, settle: bool = True) -> None:
        """Write a chunk to a port; ``settle=False`` when its reader has read every earlier byte."""
        port = self.ports.get(source)
        if port is None:
            return
        before = port.bytes_written
        try:
            n = port.write(data, settle)
        except BlockingIOError:  # the bridge's pty full: nobody is reading, as on a real port
            n = None
        if n is None:
            self.dropped[source] += 1
        # what reached the port, a cut frame's head included: the reader sees (and acknowledges) it
        self.bytes_written[source] += port.bytes_written - before

    def read(self, source: str) -> bytes:
        """What the host wrote to a port (the ground station's MAVLink to the autopilot), without waiting."""
        port = self.ports.get(source)
        if port is None:
            return b""
        try:
            return os.read(port.master, 4096)
        except (BlockingIOError, OSError):
            return b""

    def bridge_writable(self) -> bool:
        """False while the host is not reading the bridge port, so the firmware drops frames itself.

        A host that reads, only slower than the simulator writes, is waited for (``writable_soon``)."""
        port = self.ports.get("bridge")
        return True if port is None else port.writable_soon()

    def unplug(self, source: str) -> None:
        """The cable is pulled: the pty and its symlink disappear (a reader gets an error)."""
        port = self.ports.get(source)
        if port is not None:
            port.close()
            self.ports[source] = None

    def plug(self, source: str) -> None:
        """The cable is back: a new pty under the same symlink path."""
        if self.ports.get(source) is None:
            self.ports[source] = self._open(source)

    def event(self, kind: str, source: str, t_ns: int) -> None:
        if kind == "unplug":
            self.unplug(source)
        elif kind == "plug":
            self.plug(source)

    def close(self) -> None:
        for s in SOURCES:
            self.unplug(s)


def run_live(
    sim_factory: Callable[..., Simulation],
    ports: PortSet,
    duration_s: float,
    speed: float = 1.0,
    stop: threading.Event | None = None,
    tick_s: float = 0.002,
    max_lag_wall_s: float = 0.05,
    on_progress: Callable[[float, float], None] | None = None,
) -> Simulation:
    """Drive a simulation in real time x ``speed``, writing each instrument's bytes to its pty.

    ``sim_factory(bridge_writable=..., events=...)`` builds the Simulation wired to these ports.
    The clock file is anchored at the start so a daemon with ``--clock sim:DIR/clock`` stamps
    arrivals in virtual time. The bytes may trail that clock by ``max_lag_wall_s`` of host time (a
    busy machine's scheduling, which at x80 is seconds of virtual time); if they fall further
    behind, the anchor moves back to the simulator's time, so the clock never runs ahead of the
    bytes by more (the daemon's clock holds still until the new anchor passes it).
    ``ports.reanchors`` counts these. Returns when the run ends or ``stop`` is set; the truth is
    written either way.
    """
    sim = sim_factory(bridge_writable=ports.bridge_writable, events=ports.event)

    def anchor(v: float) -> tuple[float, int]:
        mono = time.monotonic_ns()
        write_anchor(ports.clock_path, sim.t0_ns + int(v * 1e9), mono, speed)
        return v, mono

    v_anchor, mono_anchor = anchor(0.0)
    max_lag = max(0.5, max_lag_wall_s * speed)
    sim.start(duration_s, lambda source, t_ns, data: ports.write(source, data))
    next_report = 0.0
    try:
        while sim.t < duration_s and not (stop is not None and stop.is_set()):
            target = v_anchor + (time.monotonic_ns() - mono_anchor) * 1e-9 * speed
            uplink = ports.read("mavlink")
            if uplink:
                sim.uplink(uplink)
            if target > sim.t:
                sim.advance(min(target, sim.t + 0.5, duration_s))  # a step at a time: stop works
            target = v_anchor + (time.monotonic_ns() - mono_anchor) * 1e-9 * speed
            if target - sim.t > max_lag:
                v_anchor, mono_anchor = anchor(sim.t)
                ports.reanchors += 1
            if on_progress is not None and sim.t >= next_report and sim.t > 0:  # after a step
                next_report = sim.t + 10.0
                on_progress(sim.t, duration_s)
            if target <= sim.t:
                time.sleep(tick_s)
    finally:
        sim.finish()
    return sim
