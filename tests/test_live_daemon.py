"""The live view never changes the log and never holds acquisition up.

The daemon runs in this process on one NMEA source whose bytes come in fixed chunks, each stamped
with its own virtual time: two runs log the same records whatever the machine's speed, so the MCAP
without the live view and with it (the real server, a reading client and a stalled one) compare
message for message.
"""

from __future__ import annotations

import math
import threading
import time

from forcemap.host.acquire.daemon import Daemon
from forcemap.host.cli.run import _pipeline_factory
from forcemap.host.fuse import calibration
from forcemap.host.live.service import LiveService
from forcemap.host.live.tee import LiveTee
from forcemap.host.log.mcap import McapLog
from forcemap.host.log.messages import Depth

from bench.live_client import LiveClient
from tests.test_daemon_support import mcap_files, nmea_line
from tests.test_live import mcap_messages

T0_NS = 1_763_000_000 * 10**9
SECONDS = 240


def _nmea(i: int) -> bytes:
    """One second of a boat on a slow circle: position, course and speed, heading, depth, wind."""
    t = time.gmtime(T0_NS // 10**9 + i)
    hhmmss = time.strftime("%H%M%S", t)
    lat = 47.0 + 0.0005 * math.sin(i / 40)
    lon = 8.0 + 0.0007 * math.cos(i / 40)
    la = f"{int(lat):02d}{(lat % 1) * 60:07.4f}"
    lo = f"{int(lon):03d}{(lon % 1) * 60:07.4f}"
    cog = (i * 360 / 251) % 360
    return b"".join(
        nmea_line(body)
        for body in (
            f"GPGGA,{hhmmss}.00,{la},N,{lo},E,1,08,0.9,1.0,M,47.0,M,,",
            f"GPRMC,{hhmmss}.00,A,{la},N,{lo},E,3.1,{cog:.1f},{time.strftime('%d%m%y', t)},,,A",
            f"HCHDT,{(cog + 5) % 360:.1f},T",
            f"SDDPT,{3.0 + math.sin(i / 17):.2f},0.3",
            f"WIMWV,{(40 + i) % 360:.1f},R,{6 + math.sin(i / 9):.1f},M,A",
        )
    )


class Recorded:
    """A transport that hands out fixed chunks and sets the clock to each chunk's time."""

    def __init__(self, clock: VirtualClock, chunks: list[tuple[int, bytes]]):
        self.clock, self.chunks, self.i = clock, chunks, 0
        self.done = threading.Event()

    def read(self) -> bytes:
        if self.i >= len(self.chunks):
            self.done.set()
            time.sleep(0.01)
            return b""
        t, data = self.chunks[self.i]
        self.i += 1
        self.clock.t = t
        return data

    def close(self) -> None:
        pass


class VirtualClock:
    name, speed = "virtual", 1.0

    def __init__(self, t0: int = T0_NS) -> None:
        self.t0 = self.t = t0

    def monotonic_ns(self) -> int:
        return self.t - self.t0

    def wall_ns(self) -> int:
        return self.t

    def note(self, source: str, what: str) -> None:
        pass  # no lockstep simulator listens


def _survey(out, live: LiveService | None = None) -> list:
    clock = VirtualClock()
    chunks = [(T0_NS + i * 10**9, _nmea(i)) for i in range(SECONDS)]
    transport = Recorded(clock, chunks)
    log = McapLog(out)
    if live is not None:
        live.attach(log)
    cal = calibration.load(None)
    daemon = Daemon(
        {"nmea": lambda: transport}, _pipeline_factory(cal, "interpolate", 1.0), log, clock=clock
    )
    runner = threading.Thread(target=daemon.run)
    runner.start()
    assert transport.done.wait(120)
    while daemon.queue.qsize():
        time.sleep(0.05)
    daemon.request_stop()
    runner.join(60)
    [path] = mcap_files(out)
    # the daemon's own status and events carry host-time fields (uptime): everything else must agree
    return [m for m in mcap_messages(path) if not m[0].startswith("/daemon/")]


def test_the_mcap_is_the_same_with_the_live_view_and_its_clients(tmp_path):
    plain = _survey(tmp_path / "plain")
    topics = {t for t, _, _ in plain}
    assert {"/fix", "/depth", "/samples", "/wind/true", "/nmea/sentence"} <= topics, topics
    live = LiveService("127.0.0.1", 0, every_s=60.0)
    url = f"ws://127.0.0.1:{live.server.port}"
    reader, stalled = LiveClient(url), LiveClient(url, stall=True)
    try:
        reader.wait_ready()
        stalled.wait_ready()
        with_live = _survey(tmp_path / "live", live)
        reader.wait_for(lambda c: c.topics().get("/samples", 0) >= 100, 60)
    finally:
        live.close()
        reader.close()
        stalled.close()
    assert with_live == plain
    got = set(reader.messages)
    assert got and {m for m in got if m[0] in topics} <= set(plain)
    assert live.tee.drops == {}  # nothing was dropped for the live view either


def test_a_publisher_that_never_takes_costs_the_log_nothing(tmp_path):
    """The tee is bounded: with nobody taking from it, every write still lands in the MCAP at once,
    and what the live view could not hold is counted, per topic."""
    log = McapLog(tmp_path)
    tee = LiveTee(maxlen=100)
    log.tee = tee.offer
    n = 5000
    for i in range(n):
        log.write("/depth", T0_NS + i, Depth(i, 3.0))
    log.close()
    assert sum(1 for m in mcap_messages(log.path) if m[0] == "/depth") == n
    assert len(tee) == 100 and tee.drops == {"/depth": n - 100} and tee.offered == n
