"""The simulator's clock drives the daemon (issue 33): in lockstep every chunk a reader queues carries
its virtual send time, in the simulator's order, with the machine as busy as it is.

The first test is the handshake with the daemon's real `Reader` and `SimClock` on the simulator's real
ptys (`PortSet`). The slow one runs `forcemap sim --lockstep` and `forcemap run` as `forcemap demo` does,
twice with one seed, the second time with two processes spinning both cores of the machine, and
finds the same samples table, row for row.
"""

from __future__ import annotations

import argparse
import queue
import subprocess
import sys
import threading

import pytest
from forcemap.host.acquire.arrival_clock import SimClock
from forcemap.host.acquire.sources import Chunk, Reader, SourceEvent, port_opener
from forcemap.host.cli.demo import survey
from forcemap.host.convert.export import samples_table
from forcemap.sim_devices.lockstep import Lockstep
from forcemap.sim_devices.ports import PortSet

T0 = 1_780_000_000 * 10**9


def _chunks(q: queue.Queue, n_bytes: int) -> list[Chunk]:
    got, total = [], 0
    while total < n_bytes:
        item = q.get(timeout=30)
        if isinstance(item, Chunk):
            got.append(item)
            total += len(item.data)
    return got


def test_each_chunk_is_stamped_at_its_send_time_and_queued_in_order(tmp_path):
    ports = PortSet(tmp_path / "ports")
    lock = Lockstep(ports, ["depth", "mavlink"], patience_s=60)
    lock.set_clock(T0)
    q: queue.Queue = queue.Queue()
    stop = threading.Event()
    clock = SimClock(ports.clock_path, wait_s=10)
    readers = [
        Reader(s, port_opener(ports.path(s), 115200), q, stop, clock) for s in ("depth", "mavlink")
    ]
    try:
        for r in readers:
            r.start()
        for s in ("depth", "mavlink"):
            assert lock.wait_news(s, "+")
        sent = []
        for k in range(200):  # interleaved sources, 10 ms apart, as the simulator's heap gives them
            source = "depth" if k % 3 else "mavlink"
            data = f"$SDDPT,{k}*00\r\n".encode()
            t_ns = T0 + (k + 1) * 10_000_000
            lock.write(source, t_ns, data)
            sent.append((source, t_ns, data))
        got = _chunks(q, sum(len(d) for _, _, d in sent))
        # a chunk may come in pieces, but each piece is stamped at its chunk's send time, in order
        assert _joined(got) == sent
        assert lock.timeouts == 0
        # a pulled cable: the reader has seen it before the simulator goes on, at the pull's time
        lock.event("unplug", "depth", T0 + 3 * 10**9)
        gone = [i for i in list(q.queue) if isinstance(i, SourceEvent)]
        assert [(e.kind, e.t_wall_ns) for e in gone] == [("disconnected", T0 + 3 * 10**9)]
        lock.event("plug", "depth", T0 + 4 * 10**9)
        lock.write("depth", T0 + 5 * 10**9, b"$SDDPT,after*00\r\n")
        assert lock.timeouts == 0
    finally:
        stop.set()
        for r in readers:
            r.join(5)
        lock.close()
        ports.close()


def test_a_daemon_that_never_answers_is_given_up_once_not_at_every_chunk(tmp_path):
    ports = PortSet(tmp_path / "ports")
    lock = Lockstep(ports, ["depth"], patience_s=0.2)
    try:
        lock.set_clock(T0)
        assert not lock.wait_news("depth", "+")  # nobody reads the port
        for k in range(50):
            lock.write("depth", T0 + k * 10**7, b"$SDDPT,1*00\r\n")
        assert lock.timeouts == 1 and ports.bytes_written["depth"] > 0
    finally:
        lock.close()
        ports.close()


def _joined(got: list[Chunk]) -> list[tuple[str, int, bytes]]:
    """Pieces of one chunk (same source and stamp, in a row) joined again."""
    out: list[tuple[str, int, bytes]] = []
    for c in got:
        if out and out[-1][0] == c.source and out[-1][1] == c.t_wall_ns:
            out[-1] = (c.source, c.t_wall_ns, out[-1][2] + c.data)
        else:
            out.append((c.source, c.t_wall_ns, c.data))
    return out


SPIN = "while True: pass"


@pytest.mark.slow
def test_the_same_seed_gives_the_same_samples_on_a_busy_machine(tmp_path):
    def run(out, spinners):
        spin = [subprocess.Popen([sys.executable, "-c", SPIN]) for _ in range(spinners)]
        try:
            args = argparse.Namespace(
                scenario="river", duration=150.0, speed=1000.0, phenomena="depth_current",
                faults="default", seed=1, live=None,
            )  # fmt: skip
            return samples_table(survey(args, out))
        finally:
            for p in spin:
                p.kill()
                p.wait()

    quiet = run(tmp_path / "a", 0)
    busy = run(tmp_path / "b", 2)  # both cores spinning, on top of whatever else the machine runs
    assert len(quiet) > 400
    assert busy.columns == quiet.columns
    assert busy.rows == quiet.rows
