"""`forcemap log info` and `forcemap log recover` on complete and truncated files."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

from forcemap.host.cli import main
from forcemap.host.cli.log import recover, scan_file
from forcemap.host.mcap_log import McapLog, read_messages
from mcap.reader import make_reader

T0 = 1_750_000_000_000_000_000


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
    assert main(["log", "info", "--json", str(path)]) == 0
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
    """A real kill -9 of a process in the middle of writing, then recover."""
    code = (
        "import sys, time\n"
        "from host.mcap_log import McapLog\n"
        "log = McapLog(sys.argv[1])\n"
        "print(log.path, flush=True)\n"
        "i = 0\n"
        "while True:\n"
        "    log.write('/a', time.time_ns(), {'i': i}); i += 1\n"
        "    time.sleep(0.001)\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(tmp_path)],
        stdout=subprocess.PIPE,
        text=True,
        cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
    )
    path = proc.stdout.readline().strip()
    time.sleep(1.5)
    killed_at = time.time_ns()
    proc.send_signal(signal.SIGKILL)
    proc.wait(10)
    count, scan = recover(path, tmp_path / "fixed.mcap")
    assert scan.truncated and count > 0
    got = [m.message["i"] for m in read_messages(tmp_path / "fixed.mcap")]
    assert got == list(range(count))
    last = max(m.log_time_ns for m in read_messages(tmp_path / "fixed.mcap"))
    assert (killed_at - last) / 1e9 <= 1.0
