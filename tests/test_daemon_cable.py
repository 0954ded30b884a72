"""A cable pull: the daemon keeps logging the other sources and reads the port again within 2 s.

Independent of machine speed: what the daemon must have logged is counted from what this test
really wrote (every frame's sequence number and write time), not from the rate it meant to write
at, and each time bound grows by the longest stall a probe thread saw in the same moments (on an
idle machine a few milliseconds; see ``StallProbe``).
"""

from __future__ import annotations

import signal
import threading
import time

import pytest
from forcemap.host.log.mcap import read_messages

from bench.live_client import LiveClient
from tests.test_daemon_support import (
    DaemonProcess,
    PtyPort,
    StallProbe,
    bridge_frame,
    depth_sentence,
    mcap_files,
    wait_drained,
)

# different lengths so the reconnect lands at different points of the backoff schedule
PULLS_S = (1.3, 2.2, 3.1)
MAX_RECONNECT_S = 2.0
PERIOD_S = 0.05


class Outage:
    """One pull: wall-clock and monotonic ns when the port went away and when it came back."""

    def __init__(self) -> None:
        self.pulled = time.time_ns()
        self.pulled_mono = time.monotonic_ns()
        self.back = self.back_mono = 0

    def replugged(self) -> None:
        self.back = time.time_ns()
        self.back_mono = time.monotonic_ns()


@pytest.mark.parametrize("live", [False, True], ids=["plain", "live_client"])
def test_cable_pull_and_replug(tmp_path, live):
    ports = {n: PtyPort(tmp_path / n) for n in ("bridge", "depth")}
    extra = ("--live", "127.0.0.1:0") if live else ()
    daemon = DaemonProcess(tmp_path / "out", {n: str(p.path) for n, p in ports.items()}, *extra)
    client = None
    stop = threading.Event()
    lock = threading.Lock()
    bridge_sent: dict[int, int] = {}  # seq -> wall ns just after the frame was written
    depth_sent: list[int] = []  # wall ns of each depth line that reached a plugged port

    def writer() -> None:
        i = 0
        while not stop.is_set():
            with lock:
                if ports["depth"].master >= 0:
                    ports["depth"].write(depth_sentence(i))
                    depth_sent.append(time.time_ns())
                ports["bridge"].write(bridge_frame(i, 1_000_000 + i * 50_000))
                bridge_sent[i] = time.time_ns()
            i += 1
            stop.wait(PERIOD_S)

    outages: list[Outage] = []
    with StallProbe() as probe:
        try:
            if live:  # a Foxglove client watching the whole time
                client = LiveClient(daemon.wait_for(lambda e: e.get("event") == "live")["connect"])
                client.wait_ready()
            daemon.wait_connected(ports)
            t = threading.Thread(target=writer)
            t.start()
            for pull_s in PULLS_S:
                time.sleep(0.5)
                with lock:
                    ports["depth"].pull()
                    outages.append(Outage())
                time.sleep(pull_s)
                with lock:
                    ports["depth"].plug()
                    outages[-1].replugged()
            time.sleep(2.5)
            stop.set()
            t.join()
            wait_drained(ports.values())
            assert daemon.stop(signal.SIGTERM) == 0
        finally:
            stop.set()
            if client is not None:
                client.close()
            for p in ports.values():
                p.close()
            if daemon.proc.poll() is None:
                daemon.proc.kill()

    files = mcap_files(tmp_path / "out")
    events = [(m.log_time_ns, m.message) for m in read_messages(files, "/daemon/event")]
    depth_times = [m.log_time_ns for m in read_messages(files, "/nmea/sentence")]
    bridge_logged = {
        m.message["seq"]: m.log_time_ns
        for m in read_messages(files, "/bridge/frame")
        if m.message.get("type") == "SAMPLE"
    }
    downs = [t for t, e in events if e["event"] == "disconnected" and e.get("source") == "depth"]
    assert len(downs) == len(PULLS_S)
    # nothing the bridge sent was lost, pulls or not
    assert set(bridge_sent) <= set(bridge_logged)
    report = []
    for out in outages:
        # the other source kept being logged while this one was unplugged: at least half of what
        # it sent during the pull was stamped before the port came back (none, if the daemon
        # waited on the missing port); a stall at the end of the pull may push the rest past it
        stall = probe.max_stall(out.pulled_mono, out.back_mono)
        during = [q for q, s in bridge_sent.items() if out.pulled < s < out.back - stall * 1e9]
        assert during, "the writer wrote nothing during the pull"
        inside = sum(bridge_logged[q] < out.back for q in during)
        assert inside >= 0.5 * len(during), (inside, len(during), stall)

        up = min(
            t
            for t, e in events
            if e["event"] == "connected" and e.get("source") == "depth" and t >= out.back
        )
        first_sent = min(s for s in depth_sent if s >= out.back)
        first_data = min(t for t in depth_times if t >= first_sent)
        reconnect_s, data_s = (up - out.back) / 1e9, (first_data - first_sent) / 1e9
        stall = probe.max_stall(out.back_mono, out.back_mono + int(max(reconnect_s, data_s) * 1e9))
        report.append((round(reconnect_s, 3), round(data_s, 3), round(stall, 3)))
        assert reconnect_s <= MAX_RECONNECT_S + stall, report
        assert data_s <= MAX_RECONNECT_S + stall, report
    print("after the port came back: (connected, first data after its write, stall) s:", report)
    if client is not None:  # and the client saw the outages as the log has them
        seen = [m for m in client.messages if m[0] == "/daemon/event"]
        assert sum(b'"disconnected"' in p and b'"depth"' in p for _, _, p in seen) == len(PULLS_S)
