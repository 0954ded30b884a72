"""`forcemap run` without a bridge: NMEA-only (several instruments, ptys and UDP) and MAVLink-only boats.

Waits are bounds on a condition ("the log holds every sentence sent"), never a fixed sleep, so the
tests hold on a busy machine.
"""

from __future__ import annotations

import json
import signal
import socket
import time
from collections import Counter
from pathlib import Path

import pytest
from forcemap.host.cli.run import nmea_sources
from forcemap.host.fuse.pipeline import Pipeline
from forcemap.host.log.mcap import read_messages

from tests.test_daemon_support import (
    DaemonProcess,
    PtyPort,
    depth_sentence,
    mavlink_packet,
    mcap_files,
    nmea_line,
    wait_drained,
)
from tests.tools import REAL

BOUND_S = 60.0  # far beyond what a busy machine needs; a failure is a lost message, not slowness


def rmc_sentence(i: int) -> bytes:
    # 12:00:00 + i s on 2026-06-01, at 47°N 8°E, 3.0 kn toward 090°
    return nmea_line(f"GPRMC,1200{i:02d}.00,A,4700.000,N,00800.000,E,3.0,90.0,010626,,,A")


def free_udp_port() -> int:
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    return port


def wait_for_topic(out: Path, topic: str, n: int) -> None:
    """Until the live log holds ``n`` messages on ``topic`` (read through its truncated tail)."""
    deadline = time.monotonic() + BOUND_S
    while time.monotonic() < deadline:
        files = mcap_files(out)
        if files and sum(1 for _ in read_messages(files, topic)) >= n:
            return
        time.sleep(0.2)
    raise TimeoutError(f"fewer than {n} {topic} messages in {out} after {BOUND_S} s")


def finish(daemon: DaemonProcess) -> Counter:
    assert daemon.stop(signal.SIGTERM) == 0
    [path] = mcap_files(daemon_out(daemon))
    return Counter(m.topic for m in read_messages(path))


def daemon_out(daemon: DaemonProcess) -> Path:
    args = daemon.proc.args
    return Path(args[args.index("-o") + 1])


def test_nmea_source_names():
    assert nmea_sources(["/dev/a", "udp:10110", "socket://h:10110?x=y"], "/dev/d") == {
        "depth": "/dev/d",
        "nmea": "/dev/a",
        "nmea2": "udp:10110",
        "nmea3": "socket://h:10110?x=y",
    }
    assert nmea_sources([], None) == {}


class Sink:
    def __init__(self):
        self.messages: list[tuple[str, dict]] = []

    def write(self, topic, log_time_ns, message):
        self.messages.append((topic, message.to_json()))  # the pipeline writes typed records

    def metadata(self, name, data):
        pass


def test_interleaved_fragments_of_two_instruments_stay_whole_lines():
    sink = Sink()
    lines = Pipeline(
        None, sink
    )  # splits each NMEA source ("nmea*", "depth*") into lines on its own
    gps = [rmc_sentence(i) for i in range(6)]
    sounder = [depth_sentence(i) for i in range(6)]
    t = 1_780_000_000_000_000_000
    for k, (a, b) in enumerate(zip(gps, sounder, strict=True)):
        for part in (slice(0, 20), slice(20, None)):  # half a line from each, in turn
            lines.feed("nmea", t + k, t + k, a[part])
            lines.feed("nmea2", t + k, t + k, b[part])
    lines.gap("nmea2", t + 10, "device_gone")
    lines.feed("nmea2", t + 11, t + 11, b"$SDDPT,9.9")  # a partial line lost in the gap ...
    lines.gap("nmea2", t + 12, "device_gone")
    lines.feed("nmea2", t + 13, t + 13, depth_sentence(7))  # ... does not spoil the next one
    sentences = [m for topic, m in sink.messages if topic == "/nmea/sentence"]
    assert len(sentences) == 13
    assert all(s["valid"] for s in sentences), [s for s in sentences if not s["valid"]]
    assert Counter(s["type"] for s in sentences) == {"RMC": 6, "DPT": 7}


def test_nmea_only_boat_with_two_instruments_on_ptys(tmp_path):
    gps, sounder = PtyPort(tmp_path / "nmea"), PtyPort(tmp_path / "nmea2")
    out = tmp_path / "out"
    daemon = DaemonProcess(out, {}, "--nmea", str(gps.path), "--depth", str(sounder.path))
    try:
        daemon.wait_connected(["nmea", "depth"])
        for i in range(10):
            a, b = rmc_sentence(i), depth_sentence(i)
            gps.write(a[:15])
            sounder.write(b[:10])
            wait_drained([gps, sounder])  # the halves reach the daemon as chunks of their own
            gps.write(a[15:])
            sounder.write(b[10:])
        wait_for_topic(out, "/nmea/sentence", 20)
        counts = finish(daemon)
    finally:
        gps.close()
        sounder.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    assert counts["/nmea/sentence"] == 20
    assert counts["/depth"] == 10
    assert counts["/fix"] == 10
    [path] = mcap_files(out)
    assert all(m.message["valid"] for m in read_messages(path, "/nmea/sentence"))
    start = next(
        m.message for m in read_messages(path, "/daemon/event") if m.message["event"] == "start"
    )
    assert start["sources"] == ["depth", "nmea"] and set(start["absent"]) == {"bridge", "mavlink"}
    # the sources metadata (issue 20): the one used per quantity, written at the end of the run
    sources = _metadata(path, "sources")
    assert json.loads(sources["position"])["chosen"] == "nmea GPRMC [hhmmss.ss 3dp]"
    assert json.loads(sources["depth"])["chosen"] == "depth SDDPT"


def _metadata(path: Path, name: str) -> dict[str, str]:
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return [dict(m.metadata) for m in make_reader(f).iter_metadata() if m.name == name][-1]


def test_nmea_over_udp_like_a_multiplexer(tmp_path):
    port = free_udp_port()
    out = tmp_path / "out"
    daemon = DaemonProcess(out, {}, "--nmea", f"udp:127.0.0.1:{port}")
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        daemon.wait_connected(["nmea"])
        for i in range(12):  # a datagram may carry several sentences, as multiplexers send them
            tx.sendto(rmc_sentence(i) + depth_sentence(i), ("127.0.0.1", port))
        wait_for_topic(out, "/nmea/sentence", 24)
        counts = finish(daemon)
    finally:
        tx.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    assert counts["/nmea/sentence"] == 24
    assert counts["/fix"] == 12 and counts["/depth"] == 12


def test_mavlink_only_boat_over_udp(tmp_path):
    port = free_udp_port()
    out = tmp_path / "out"
    daemon = DaemonProcess(out, {}, "--mavlink", f"udpin:127.0.0.1:{port}")
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        daemon.wait_connected(["mavlink"])
        for i in range(30):
            tx.sendto(mavlink_packet(i), ("127.0.0.1", port))
        wait_for_topic(out, "/mavlink/GLOBAL_POSITION_INT", 30)
        counts = finish(daemon)
    finally:
        tx.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    assert counts["/mavlink/GLOBAL_POSITION_INT"] == 30
    assert counts["/fix"] == 30


def test_nmea_connection_strings():
    from forcemap.host.acquire.sources import SerialOpener, UdpOpener, nmea_opener

    udp = nmea_opener("udp:10110")  # a broadcast: every interface
    assert isinstance(udp, UdpOpener) and (udp.host, udp.port) == ("0.0.0.0", 10110)
    one = nmea_opener("udpin:127.0.0.1:10110")
    assert (one.host, one.port) == ("127.0.0.1", 10110)
    tcp = nmea_opener("tcp:192.168.4.1:10110")
    assert isinstance(tcp, SerialOpener) and tcp.url == "socket://192.168.4.1:10110"
    serial_port = nmea_opener("/dev/ttyUSB0,38400")
    assert (serial_port.url, serial_port.baudrate) == ("/dev/ttyUSB0", 38400)
    assert nmea_opener("/dev/ttyUSB0").baudrate == 4800
    for bad in ("udp:host:notaport", "udp:70000", "udp:"):
        with pytest.raises(ValueError, match="port from 1 to 65535"):
            nmea_opener(bad)


REAL_NMEA = REAL / "nmea"


def independent_counts(lines: list[bytes]) -> Counter:
    """Sentence types of the lines whose checksum is right, computed here without the parser."""
    counts: Counter = Counter()
    for line in lines:
        body, star, given = line.strip()[1:].partition(b"*")
        check = 0
        for ch in body:
            check ^= ch
        if star and given[:2].upper() == f"{check:02X}".encode():
            counts[body.split(b",")[0][-3:].decode()] += 1
    return counts


def test_a_real_capture_streamed_live_is_logged_line_for_line(tmp_path):
    """The first 3000 lines of PacCupStart, through a pty, as a boat's NMEA network would send them."""
    capture = REAL_NMEA / "PacCupStartNMEA.txt"
    if not capture.is_file():
        pytest.fail(f"the real capture {capture} is missing", pytrace=False)
    lines = capture.read_bytes().splitlines(keepends=True)[:3000]
    expected = independent_counts(lines)
    assert sum(expected.values()) == 3000  # checked by hand: this stretch has no corrupt line
    assert expected["VWR"] == 109 and expected["DBT"] == 109 and expected["RMC"] == 54  # grep -c
    port = PtyPort(tmp_path / "nmea")
    out = tmp_path / "out"
    daemon = DaemonProcess(out, {}, "--nmea", str(port.path))
    try:
        daemon.wait_connected(["nmea"])
        for k in range(0, len(lines), 100):
            port.write(b"".join(lines[k : k + 100]))
            wait_drained([port])
        wait_for_topic(out, "/nmea/sentence", 3000)
        counts = finish(daemon)
    finally:
        port.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    [path] = mcap_files(out)
    sentences = [m.message for m in read_messages(path, "/nmea/sentence")]
    assert counts["/nmea/sentence"] == 3000
    assert all(s["valid"] for s in sentences)
    got = Counter(s["text"].split(",")[0][-3:] for s in sentences)
    assert got == expected
    assert counts["/depth"] == expected["DBT"] + expected["MTW"]
    assert counts["/fix"] > 0
