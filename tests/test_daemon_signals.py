"""SIGTERM and SIGINT close the log cleanly: the file has its summary and opens by seeking."""

from __future__ import annotations

import base64
import signal
import time

import pytest
from forcemap.host.log.mcap import read_messages
from mcap.reader import make_reader

from tests.test_daemon_support import (
    DaemonProcess,
    PtyPort,
    bridge_frame,
    depth_sentence,
    mcap_files,
    wait_drained,
)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_closes_the_log_with_a_summary(tmp_path, sig):
    ports = {n: PtyPort(tmp_path / n) for n in ("bridge", "depth")}
    daemon = DaemonProcess(tmp_path / "out", {n: str(p.path) for n, p in ports.items()}, "--raw")
    sent = b""
    try:
        daemon.wait_connected(ports)
        for i in range(40):
            sent += bridge_frame(i, 1_000_000 + i * 250_000)
            ports["bridge"].write(bridge_frame(i, 1_000_000 + i * 250_000))
            ports["depth"].write(depth_sentence(i))
            time.sleep(0.005)
        wait_drained(ports.values())
        assert daemon.stop(sig) == 0
    finally:
        for p in ports.values():
            p.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    [path] = mcap_files(tmp_path / "out")
    with open(path, "rb") as f:
        reader = make_reader(f)  # the seeking reader: needs the summary and footer
        summary = reader.get_summary()
        topics = {c.topic: c.id for c in summary.channels.values()}
        counts = summary.statistics.channel_message_counts
        metadata = {m.name for m in reader.iter_metadata()}
    assert counts[topics["/bridge/frame"]] == 40
    assert "/daemon/status" in topics and "/daemon/event" in topics
    assert {"forcemap", "boat_toml", "config", "calibration"} <= metadata
    stop = daemon.wait_for(lambda e: e.get("event") == "stop")
    assert stop["files"] == [str(path)]
    assert daemon.wait_for(lambda e: e.get("event") == "signal")["signal"] == sig.name
    raw = [base64.b64decode(m.message["data"]) for m in read_messages(path, "/raw/bridge")]
    assert b"".join(raw) == sent  # --raw keeps every byte as read


def test_bad_config_is_one_clear_error(tmp_path):
    bad = tmp_path / "boat.toml"
    bad.write_text("[anemometer]\nmps_per_hz = 'fast'\n")
    daemon = DaemonProcess(
        tmp_path / "out", {"depth": str(tmp_path / "nothing")}, "--boat", str(bad)
    )
    rc = daemon.proc.wait(30)
    daemon._thread.join(5)
    assert rc == 2
    text = "".join(daemon.lines)
    assert "mps_per_hz" in text and "Traceback" not in text
    assert not mcap_files(tmp_path / "out")


def test_rotation_gives_complete_files_each_with_the_metadata(tmp_path):
    port = PtyPort(tmp_path / "bridge")
    daemon = DaemonProcess(tmp_path / "out", {"bridge": str(port.path)}, "--rotate-mb", "0.03")
    try:
        daemon.wait_connected(["bridge"])
        for i in range(600):
            port.write(bridge_frame(i, 1_000_000 + i * 250_000))
            if i % 50 == 0:
                time.sleep(0.05)
        wait_drained([port])
        assert daemon.stop(signal.SIGTERM) == 0
    finally:
        port.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    files = mcap_files(tmp_path / "out")
    assert len(files) >= 2
    frames = 0
    for path in files:
        with open(path, "rb") as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            names = {m.name for m in reader.iter_metadata()}
        assert {"forcemap", "boat_toml", "calibration", "config"} <= names
        topics = {c.id: c.topic for c in summary.channels.values()}
        frames += sum(
            n
            for cid, n in summary.statistics.channel_message_counts.items()
            if topics[cid] == "/bridge/frame"
        )
    assert frames == 600
    assert len(daemon.wait_for(lambda e: e.get("event") == "stop")["files"]) == len(files)


def test_command_line_errors_exit_2_before_anything_starts(tmp_path, capsys):
    from forcemap.host.cli import main

    assert main(["run", "-o", str(tmp_path / "a")]) == 2
    assert "at least one of" in capsys.readouterr().err
    assert main(["run", "--mavlink", "udpout:10.0.0.1:14550", "-o", str(tmp_path / "b")]) == 2
    assert "udpout" in capsys.readouterr().err
    assert main(["run", "--depth", "x", "--clock", "gps", "-o", str(tmp_path / "c")]) == 2
    assert not any(tmp_path.iterdir())
