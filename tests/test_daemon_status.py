"""The daemon in-process: live status view, structured event lines, an absent source, a bad pipeline.

Independent of machine speed: every transient state (a source connected, a live frame drawn while
one source reads and another waits) is waited for with a generous deadline, never slept for.
"""

from __future__ import annotations

import io
import json
import threading
import time

from forcemap.host.acquire.daemon import Daemon
from forcemap.host.acquire.sources import port_opener
from forcemap.host.acquire.status import Reporter
from forcemap.host.fuse.pipeline import Pipeline
from forcemap.host.log.mcap import McapLog, has_footer, read_messages

from tests.test_daemon_support import PtyPort, depth_sentence


def _run(daemon: Daemon, work) -> None:
    t = threading.Thread(target=daemon.run)
    t.start()
    try:
        work()
    finally:
        daemon.request_stop()
        t.join(20)
    assert not t.is_alive()


def _wait(pred, timeout=10.0):
    deadline = time.monotonic() + timeout
    while not pred():
        assert time.monotonic() < deadline
        time.sleep(0.02)


CLEAR = "\x1b[H\x1b[J"  # the live view redraws from the top of a cleared screen


def running(frame: str) -> bool:
    """A live frame drawn while depth was read and bridge was waited for."""
    rows = {line.split()[0]: line for line in frame.splitlines() if line.split()}
    return "reading" in rows.get("depth", "") and "WAITING" in rows.get("bridge", "")


def test_live_view_shows_rates_errors_fix_and_file(tmp_path):
    port = PtyPort(tmp_path / "depth")
    screen = io.StringIO()
    log = McapLog(tmp_path / "out")
    daemon = Daemon(
        {"depth": port_opener(str(port.path)), "bridge": port_opener(str(tmp_path / "none"))},
        lambda sink: Pipeline(None, sink),
        log,
        reporter=Reporter(screen, live=True),
        absent=["mavlink"],
        status_interval_s=0.1,
    )

    def work():
        _wait(lambda: daemon.readers["depth"].stats.connected)
        for i in range(30):
            port.write(depth_sentence(i))
        port.write(b"$SDDPT,garbage*00\r\n")
        _wait(lambda: daemon.status.topic_counts.get("/depth", 0) >= 30)
        # a frame drawn while one source reads and another waits: waited for, not slept for
        _wait(lambda: any(running(f) for f in screen.getvalue().split(CLEAR)[:-1]))

    try:
        _run(daemon, work)
    finally:
        port.close()
    text = screen.getvalue()
    frames = text.split(CLEAR)
    last = frames[-1]
    assert any(running(f) for f in frames[:-1])  # while it ran
    assert "depth" in last and "stopped" in last
    assert "bridge" in last and "port_missing" in last
    assert "mavlink" in last and "not given" in last
    assert "/nmea/sentence" in last and "last fix  none yet" in last
    assert "nmea.rejected 1" in last  # NMEA counters are keyed by the decoder
    assert str(log.path) in last
    assert has_footer(log.path)


def test_quiet_mode_writes_one_json_line_per_event(tmp_path):
    lines = io.StringIO()
    log = McapLog(tmp_path / "out")
    daemon = Daemon(
        {"bridge": port_opener(str(tmp_path / "none"))},
        lambda sink: Pipeline(None, sink),
        log,
        reporter=Reporter(lines, live=False),
    )
    _run(daemon, lambda: _wait(lambda: daemon.readers["bridge"].stats.disconnects >= 1))
    events = [json.loads(x) for x in lines.getvalue().splitlines()]
    kinds = [e["event"] for e in events]
    assert kinds[0] == "start" and kinds[-2:] == ["final_status", "stop"]
    assert {"event": "disconnected", "source": "bridge", "reason": "port_missing"}.items() <= next(
        e for e in events if e["event"] == "disconnected"
    ).items()


class Exploding:
    """A pipeline whose every call raises: the daemon must log on regardless."""

    def __init__(self, sink):
        self.sink = sink

    def feed(self, *a):
        raise RuntimeError("boom")

    def gap(self, *a):
        raise RuntimeError("boom")

    def counters(self):
        raise RuntimeError("boom")

    def flush(self):
        raise RuntimeError("boom")

    def close(self):
        raise RuntimeError("boom")


def test_a_failing_pipeline_is_counted_not_fatal(tmp_path):
    port = PtyPort(tmp_path / "depth")
    lines = io.StringIO()
    log = McapLog(tmp_path / "out")
    daemon = Daemon(
        {"depth": port_opener(str(port.path))},
        Exploding,
        log,
        reporter=Reporter(lines, live=False),
        status_interval_s=0.1,
    )

    def work():
        _wait(lambda: daemon.readers["depth"].stats.connected)
        for i in range(20):
            port.write(depth_sentence(i))
            time.sleep(0.01)
        _wait(lambda: daemon.status.errors.get("pipeline_depth", 0) >= 1)
        port.pull()
        _wait(lambda: daemon.status.errors.get("pipeline_gap", 0) >= 1)

    try:
        _run(daemon, work)
    finally:
        port.close()
    assert has_footer(log.path)
    [final] = [m.message for m in read_messages(log.path, "/daemon/status")][-1:]
    assert final["errors"]["pipeline_depth"] >= 1
    reported = [json.loads(x) for x in lines.getvalue().splitlines()]
    assert sum(e["event"] == "error" and e["reason"] == "pipeline_depth" for e in reported) <= 5


def test_raw_bytes_are_kept_when_the_pipeline_cannot_be_built(tmp_path):
    import base64

    def broken(sink):
        raise ImportError("host.pipeline is broken")

    port = PtyPort(tmp_path / "depth")
    lines = io.StringIO()
    log = McapLog(tmp_path / "out")
    daemon = Daemon(
        {"depth": port_opener(str(port.path))},
        broken,
        log,
        reporter=Reporter(lines, live=False),
    )
    sent = b"".join(depth_sentence(i) for i in range(20))

    def work():
        _wait(lambda: daemon.readers["depth"].stats.connected)
        port.write(sent)
        _wait(lambda: daemon.readers["depth"].stats.bytes >= len(sent))

    try:
        _run(daemon, work)
    finally:
        port.close()
    raw = b"".join(
        base64.b64decode(m.message["data"]) for m in read_messages(log.path, "/raw/depth")
    )
    assert raw == sent
    assert any(
        json.loads(x).get("reason") == "pipeline_unavailable" for x in lines.getvalue().splitlines()
    )
