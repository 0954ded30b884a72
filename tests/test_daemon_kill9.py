"""`kill -9` at 20 random moments: every file stays readable and at most the last second is lost."""

from __future__ import annotations

import random
import signal
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from forcemap.host.cli.log import recover
from forcemap.host.mcap_log import FileScan, read_messages
from mcap.reader import make_reader

from tests.test_daemon_support import (
    DaemonProcess,
    PtyPort,
    bridge_frame,
    depth_sentence,
    mcap_files,
)

ROUNDS = 20
PARALLEL = 4
NMEA_HZ = 50
MAX_LOSS_S = 1.0


def _one_round(tmp_path, k: int, delay_s: float) -> dict:
    base = tmp_path / f"round{k:02d}"
    base.mkdir()
    ports = {n: PtyPort(base / n) for n in ("bridge", "depth")}
    daemon = DaemonProcess(base / "out", {n: str(p.path) for n, p in ports.items()})
    sent: list[int] = []  # wall-clock ns at which each NMEA line was written
    stop = threading.Event()

    def writer() -> None:
        i = 0
        while not stop.is_set():
            ports["depth"].write(depth_sentence(i))
            if i % 5 == 0:
                ports["bridge"].write(bridge_frame(i // 5, 1_000_000 + i * 20_000))
            sent.append(time.time_ns())
            i += 1
            stop.wait(1 / NMEA_HZ)

    try:
        daemon.wait_connected(ports)
        t = threading.Thread(target=writer)
        t.start()
        time.sleep(delay_s)
        t_kill = time.time_ns()
        daemon.proc.send_signal(signal.SIGKILL)
        daemon.proc.wait(10)
        stop.set()
        t.join()
    finally:
        stop.set()
        for p in ports.values():
            p.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    files = mcap_files(base / "out")
    times = []
    truncated = 0
    for path in files:
        scan = FileScan(path)
        times += [m.log_time_ns for m in read_messages(path, "/nmea/sentence", scan=scan)]
        truncated += scan.truncated
        # and `forcemap log recover` turns it into a complete file with the same messages
        fixed = base / "fixed.mcap"
        count, _ = recover(path, fixed)
        with open(fixed, "rb") as f:
            assert make_reader(f).get_summary().statistics.message_count == count
        assert count == sum(1 for _ in read_messages(path))
    last = max(times, default=None)
    # lines written more than 1 s before the kill must all be in the file
    due = sum(1 for s in sent if s <= t_kill - MAX_LOSS_S * 1e9)
    return {
        "files": len(files),
        "loss_s": (t_kill - last) / 1e9 if last else delay_s,
        "recorded": len(times),
        "due": due,
        "delay_s": delay_s,
        "truncated": truncated,
    }


def test_kill9_at_random_moments_loses_at_most_one_second(tmp_path):
    rng = random.Random(20261121)
    delays = [rng.uniform(0.05, 3.0) for _ in range(ROUNDS)]
    with ThreadPoolExecutor(PARALLEL) as pool:
        results = list(pool.map(lambda kd: _one_round(tmp_path, *kd), enumerate(delays)))
    worst = max(r["loss_s"] for r in results)
    print(
        f"kill -9 x{ROUNDS}: worst loss {worst:.3f} s; ",
        sorted(round(r["loss_s"], 3) for r in results),
    )
    for r in results:
        assert r["files"] == 1, r
        assert r["loss_s"] <= MAX_LOSS_S, r
        assert r["recorded"] >= r["due"], r
    assert sum(r["truncated"] for r in results) == ROUNDS  # they really were killed mid-file
