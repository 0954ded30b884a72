"""The same firmware files under the real unix-port ``micropython`` binary, on PinBase fakes.

20 simulated minutes from a schedule file: 10 Hz anemometer with 0.3 ms bounce, four wheels, the
host not reading for 2 s, a reset after the ticks_us wrap. Frames go through a pty to pyserial.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from forcemap.protocol import wire

from tests import tools
from tests.bridge_scenario import Host, check_boot, openpty_raw

ROOT = Path(__file__).resolve().parents[1]
HARNESS = ROOT / "sim_devices" / "upy" / "bridge_harness.py"

MHZ = (10_000, 3_700, 5_300, 8_900, 13_100)
OFFSETS = (1_234, 9_153, 17_072, 24_991, 32_910)
END = 1_200_000_000
RESET = 1_150_000_000
DEAF = (40_000_000, 42_000_000)


def int_edges(mhz: int, start: int, stop: int) -> list[int]:
    """The harness's edge formula: start + k*10**9//mHz while < stop."""
    out = []
    k = 0
    while True:
        t = start + k * 1_000_000_000 // mhz
        if t >= stop:
            return out
        out.append(t)
        k += 1


def schedule(board: str, ticks_start: int, end: int, deaf, reset) -> str:
    lines = [f"board {board}", "seed 7", f"ticks_start {ticks_start}", f"end {end}", "vane 29527"]
    for ch in range(5):
        bounce = " 300 2" if ch == 0 else ""
        lines.append(f"rate {ch} {MHZ[ch]} {OFFSETS[ch]} {end}{bounce}")
    if deaf:
        lines.append(f"deaf {deaf[0]} {deaf[1]}")
    if reset:
        lines.append(f"reset {reset} 3")
    return "\n".join(lines) + "\n"


def run_harness(tmp_path, board, ticks_start=0, end=END, deaf=DEAF, reset=RESET):
    sched = tmp_path / "schedule.txt"
    sched.write_text(schedule(board, ticks_start, end, deaf, reset))
    master, slave = openpty_raw()
    host = Host(os.ttyname(slave))  # the host side is open before the board starts
    proc = subprocess.Popen(
        [tools.micropython(), str(HARNESS), str(tools.board_lib()), str(sched)],
        stdout=master,
        stderr=subprocess.PIPE,
    )
    try:
        while proc.poll() is None:
            host.read_available(wait_s=0.05)
        host.drain(idle_s=0.3)
    finally:
        err = proc.stderr.read().decode()
        proc.wait()
        host.close()
        os.close(master)
        os.close(slave)
    assert proc.returncode == 0, err
    return host


@pytest.mark.parametrize("board", ["nano_rp2040", "nano_esp32"])
def test_upy_twenty_minutes(tmp_path, board):
    host = run_harness(tmp_path, board)
    frames = host.frames
    assert host.dec.rejected() == 0
    boot_ids = list(dict.fromkeys(f.boot_id for f in frames))
    assert len(boot_ids) == 2 and host.tracker.resets == 1
    edges = [int_edges(MHZ[ch], OFFSETS[ch], END) for ch in range(5)]

    first = [f for f in frames if f.boot_id == boot_ids[0] and f.msg_type == wire.SAMPLE]
    second = [f for f in frames if f.boot_id == boot_ids[1] and f.msg_type == wire.SAMPLE]
    assert first[-1].t_us > 1 << 30  # across the ticks_us wrap
    # the 2 s the host did not read: frames dropped on the device, flagged on the next one
    boot0 = [f for f in frames if f.boot_id == boot_ids[0]]
    gaps = [
        (a, b) for a, b in zip(boot0, boot0[1:], strict=False) if wire.seq_delta(a.seq, b.seq) > 1
    ]
    assert [(a.t_us, b.t_us) for a, b in gaps] == [(DEAF[0] - 250_000, DEAF[1])]
    after = [f for f in frames if f.boot_id == boot_ids[0] and f.t_us >= DEAF[1]][0]
    assert after.flags & wire.FLAG_DROPPED_BEFORE

    from forcemap.host.decode.pulses import PulseTracker

    tr = PulseTracker()
    rates = None
    for f in first:
        rates = tr.update(f) or rates
    check_boot(first, 0, edges, [tr.total(ch) for ch in range(5)], rates)
    check_boot(
        second, RESET, edges, [host.tracker.total(ch) for ch in range(5)], host.rates[boot_ids[1]]
    )

    hello = [f for f in frames if f.msg_type == wire.HELLO]
    assert [h.fields["reset_cause"] for h in hello] == [1, 3]
    last_status = [f for f in boot0 if f.msg_type == wire.STATUS][-1]
    st = last_status.fields
    assert st["frames_dropped"] == 10  # 8 SAMPLEs and 2 STATUS in [40 s, 42 s)
    bounces = [e + d for e in edges[0] for d in (150, 300)]
    assert st["bounce_rejects"] == sum(1 for b in bounces if b <= last_status.t_us)
    assert all(abs(f.fields["vane_raw"] - 29527) <= 8 for f in first)


def test_upy_wrap_soon_after_boot(tmp_path):
    """ticks_us starts 30 s before its wrap, as after a long uptime."""
    end = 90_000_000
    host = run_harness(tmp_path, "nano_rp2040", (1 << 30) - 30_000_000, end, None, None)
    samples = [f for f in host.frames if f.msg_type == wire.SAMPLE]
    t = [f.t_us for f in samples]
    assert t == list(range(0, end, 250_000))  # u64 device time, no jump at the wrap
    edges = [int_edges(MHZ[ch], OFFSETS[ch], end) for ch in range(5)]
    check_boot(
        samples,
        0,
        edges,
        [host.tracker.total(ch) for ch in range(5)],
        host.rates[samples[0].boot_id],
    )
