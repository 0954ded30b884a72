"""A cable pull: the daemon keeps logging the other sources and reads the port again within 2 s."""

from __future__ import annotations

import signal
import threading
import time

from forcemap.host.mcap_log import read_messages

from tests.test_daemon_support import (
    DaemonProcess,
    PtyPort,
    bridge_frame,
    depth_sentence,
    mcap_files,
)

# different lengths so the reconnect lands at different points of the backoff schedule
PULLS_S = (1.3, 2.2, 3.1)
MAX_RECONNECT_S = 2.0


def test_cable_pull_and_replug(tmp_path):
    ports = {n: PtyPort(tmp_path / n) for n in ("bridge", "depth")}
    daemon = DaemonProcess(tmp_path / "out", {n: str(p.path) for n, p in ports.items()})
    stop = threading.Event()
    lock = threading.Lock()

    def writer() -> None:
        i = 0
        while not stop.is_set():
            with lock:
                ports["depth"].write(depth_sentence(i))
                ports["bridge"].write(bridge_frame(i, 1_000_000 + i * 50_000))
            i += 1
            stop.wait(0.05)

    outages = []  # (pulled_ns, back_ns)
    try:
        daemon.wait_connected(ports)
        t = threading.Thread(target=writer)
        t.start()
        for pull_s in PULLS_S:
            time.sleep(0.5)
            with lock:
                ports["depth"].pull()
            pulled = time.time_ns()
            time.sleep(pull_s)
            with lock:
                ports["depth"].plug()
            outages.append((pulled, time.time_ns()))
        time.sleep(2.5)
        stop.set()
        t.join()
        assert daemon.stop(signal.SIGTERM) == 0
    finally:
        stop.set()
        for p in ports.values():
            p.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()

    files = mcap_files(tmp_path / "out")
    events = [(m.log_time_ns, m.message) for m in read_messages(files, "/daemon/event")]
    depth_times = [m.log_time_ns for m in read_messages(files, "/nmea/sentence")]
    bridge_times = [m.log_time_ns for m in read_messages(files, "/bridge/frame")]
    downs = [t for t, e in events if e["event"] == "disconnected" and e.get("source") == "depth"]
    assert len(downs) == len(PULLS_S)
    latencies = []
    for (pulled, back), pull_s in zip(outages, PULLS_S, strict=True):
        up = min(
            t
            for t, e in events
            if e["event"] == "connected" and e.get("source") == "depth" and t >= back
        )
        first_data = min(t for t in depth_times if t >= back)
        latencies.append(((up - back) / 1e9, (first_data - back) / 1e9))
        # the other source kept being logged while this one was unplugged
        assert sum(pulled < t < back for t in bridge_times) >= pull_s / 0.05 * 0.5
    print("reconnect latency (connected, first data) after the port came back:", latencies)
    assert all(data <= MAX_RECONNECT_S for _, data in latencies)
