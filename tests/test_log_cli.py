"""`forcemap log info` and `forcemap log recover` on complete and truncated files."""

from __future__ import annotations

import json
import signal
import struct
import subprocess
import sys
import time

from forcemap.host.cli import main
from forcemap.host.convert.log_info import recover, scan_file
from forcemap.host.log.mcap import McapLog, read_messages
from mcap.reader import make_reader

T0 = 1_750_000_000_000_000_000
MAX_LOSS_S = 1.0


def _log(tmp_path, n=3000):
    with McapLog(tmp_path / "logs", chunk_size=8192) as log:
        log.metadata("boat_toml", {"path": "boat.toml", "text": ""})
        for i in range(n):
            t = T0 + i * 20_000_000  # 50 Hz
            if not 1000 <= i < 1200:  # a 4 s hole
                log.write("/nmea/sentence", t, {"text": f"$X{i}"})
            if i % 50 == 0:
                log.write(
                    "/diagnostics",
                    t,
                    {"counters": {"depth": {"rejected": i // 50, "accepted": i}}},
                )
        log.write(
            "/daemon/event",
            T0 + 1000 * 20_000_000,
            {"event": "disconnected", "source": "depth", "reason": "device_gone"},
        )
        log.write(
            "/daemon/event", T0 + 1200 * 20_000_000, {"event": "connected", "source": "depth"}
        )
    return log.path


def test_info_reports_channels_duration_gaps_and_counters(tmp_path, capsys):
    path = _log(tmp_path)
    assert main(["log", "info", str(path)]) == 0
    text = capsys.readouterr().out
    assert "complete" in text and "/nmea/sentence" in text and "2800" in text
    assert "boat_toml" in text
    assert "depth" in text and "4.00 s" in text  # the outage, from the daemon's events
    assert "depth.rejected" in text
    assert main(["log", "info", "--json", "-", str(path)]) == 0
    [info] = json.loads(capsys.readouterr().out)
    assert info["topics"]["/nmea/sentence"]["count"] == 2800
    assert abs((info["end_ns"] - info["start_ns"]) / 1e9 - 2999 * 0.02) < 1e-6
    [gap] = info["gaps"]
    assert gap["topic"] == "/nmea/sentence" and abs(gap["length_s"] - 4.02) < 1e-6
    assert info["outages"][0]["length_s"] == 4.0
    assert info["errors"] == {"depth.rejected": 59}  # accepted counts are not errors


def test_info_and_recover_on_a_truncated_file(tmp_path, capsys):
    path = _log(tmp_path)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    info = scan_file(cut)
    assert info.truncated and not info.complete
    readable = sum(t.count for t in info.topics.values())
    assert readable > 0
    assert main(["log", "info", str(cut)]) == 0
    assert "TRUNCATED" in capsys.readouterr().out

    out = tmp_path / "fixed.mcap"
    assert main(["log", "recover", str(cut), "-o", str(out)]) == 0
    with open(out, "rb") as f:
        reader = make_reader(f)  # seeking: needs index and summary
        summary = reader.get_summary()
        assert summary.statistics.message_count == readable
        assert [m.name for m in reader.iter_metadata()] == ["boat_toml"]
        assert len(summary.chunk_indexes) > 0
    before = [tuple(m) for m in read_messages(cut)]
    assert [tuple(m) for m in read_messages(out)] == before
    # default output name, and refusing to overwrite the input
    assert main(["log", "recover", str(cut)]) == 0
    assert (tmp_path / "cut-recovered.mcap").exists()
    assert main(["log", "recover", str(cut), "-o", str(cut)]) == 2


def test_recover_a_file_from_a_killed_writer(tmp_path):
    """A real kill -9 of a process in the middle of writing, then recover.

    The writer notes its last message in a side file after every write (os.pwrite: it survives
    the kill), so the loss is measured on the writer's own clock, from its last write: time in
    which a busy machine did not run it, before the kill, is not data it could have written.
    """
    progress = tmp_path / "progress"
    code = (
        "import os, struct, sys, time\n"
        "from forcemap.host.log.mcap import McapLog\n"
        "log = McapLog(sys.argv[1])\n"
        "fd = os.open(sys.argv[2], os.O_RDWR | os.O_CREAT)\n"
        "print(log.path, flush=True)\n"
        "i = 0\n"
        "while True:\n"
        "    t = time.time_ns()\n"
        "    log.write('/a', t, {'i': i})\n"
        "    os.pwrite(fd, struct.pack('<qq', i, t), 0); i += 1\n"
        "    time.sleep(0.001)\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(tmp_path / "logs"), str(progress)],
        stdout=subprocess.PIPE,
        text=True,
    )
    path = proc.stdout.readline().strip()

    def last_written() -> tuple[int, int]:
        data = progress.read_bytes() if progress.exists() else b""
        return struct.unpack("<qq", data) if len(data) == 16 else (-1, 0)

    # 1.5 s of writing by the writer's own clock: several flush intervals
    first = None
    while True:
        i, t = last_written()
        if i >= 0:
            first = t if first is None else first
            if t - first >= 1.5e9:
                break
        assert proc.poll() is None
        time.sleep(0.01)
    killed_at = time.time_ns()
    proc.send_signal(signal.SIGKILL)
    proc.wait(10)
    last_i, last_t = last_written()
    count, scan = recover(path, tmp_path / "fixed.mcap")
    assert scan.truncated and count > 0
    got = [m.message["i"] for m in read_messages(tmp_path / "fixed.mcap")]
    assert got == list(range(count))
    assert count <= last_i + 1  # nothing invented
    last = max(m.log_time_ns for m in read_messages(tmp_path / "fixed.mcap"))
    print(
        f"killed {(killed_at - last_t) / 1e9:.3f} s after the last write; lost its last "
        f"{(last_t - last) / 1e9:.3f} s ({last_i + 1 - count} messages)"
    )
    assert (last_t - last) / 1e9 <= MAX_LOSS_S
