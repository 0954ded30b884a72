"""Firmware pieces on their own: the pulse ISR (lockout, wraps, no allocation), the vane average,
the bridge's schedule and drop accounting, and a long calm longer than ticks_diff's range."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from forcemap.firmware_bridge import config
from forcemap.firmware_bridge.bridge import Bridge
from forcemap.firmware_bridge.pulse import PulseCounter
from forcemap.firmware_bridge.vane import Vane
from forcemap.protocol import wire
from forcemap.sim_devices.bridge_emu import EmulatedBridge
from forcemap.sim_devices.machine_emu import ADC, TICKS_PERIOD, Pin, VirtualClock

from tests import tools

ROOT = Path(__file__).resolve().parents[1]


def fire_at(clock, pin, times):
    for t in times:
        clock.now = t
        pin.fire()


def test_lockout_rejects_bounce_and_keeps_true_edges():
    clock = VirtualClock()
    pin = Pin("D2")
    pc = PulseCounter(pin, clock, lockout_us=1500)
    fire_at(clock, pin, [10_000, 10_100, 10_300, 11_499, 11_500, 20_000, 20_200])
    count, last, period = pc.snapshot()
    assert (count, last, period) == (3, 20_000, 8_500)
    assert pc.rejects() == 4


def test_period_across_ticks_wrap():
    clock = VirtualClock(ticks_start=TICKS_PERIOD - 40)
    pin = Pin("D3")
    pc = PulseCounter(pin, clock, lockout_us=0)
    fire_at(clock, pin, [0, 100])
    count, last, period = pc.snapshot()
    assert (count, last, period) == (2, 60, 100)


def test_count_wraps_at_count_mod():
    clock = VirtualClock()
    pin = Pin("D4")
    pc = PulseCounter(pin, clock, lockout_us=0)
    pc._st[0] = wire.COUNT_MOD - 2
    fire_at(clock, pin, [1, 2, 3])
    assert pc.snapshot()[0] == 1


def test_vane_average_rounds():
    class Seq:
        vals = [100, 101, 101, 101]

        def read_u16(self):
            v = self.vals.pop(0)
            self.vals.append(v)
            return v

    assert Vane(Seq(), 4).read() == 101
    adc = ADC(noise_v=0.0)
    adc.set_voltage(3.3)
    assert Vane(adc, 8).read() == 65535
    adc.set_voltage(0.0)
    assert Vane(adc, 8).read() == 0


def test_poll_schedule_and_overrun():
    clock = VirtualClock()
    out = []

    class Out:
        def write(self, b):
            out.append(wire.decode_frame(b))
            return len(b)

    pins = [Pin(i) for i in range(5)]
    counters = [PulseCounter(p, clock) for p in pins]
    adc = ADC(noise_v=0.0)
    b = Bridge(counters, Vane(adc, 2), Out(), clock, boot_id=7)
    b.start()
    assert b.poll() == 250_000
    clock.now = 250_000
    assert b.poll() == 250_000
    clock.now = 1_900_000  # the loop was late: one overrun, schedule restarts from now
    b.poll()
    assert b.loop_overruns == 1
    types = [f.msg_type for f in out]
    assert types == [wire.HELLO, wire.SAMPLE, wire.SAMPLE, wire.SAMPLE, wire.STATUS]
    assert [f.seq for f in out] == [0, 1, 2, 3, 4]
    assert out[0].fields["sample_period_us"] == config.SAMPLE_PERIOD_US


def test_not_writable_drops_and_flags_next_frame():
    sent = []
    ok = {"v": True}
    emu = EmulatedBridge(lambda b: sent.append(b) or len(b), writable=lambda: ok["v"])
    emu.advance_to(500_000)
    ok["v"] = False
    emu.advance_to(1_500_000)
    ok["v"] = True
    emu.advance_to(1_750_000)
    frames = [wire.decode_frame(b) for b in sent]
    assert emu.firmware.frames_dropped == 5  # 4 SAMPLEs + 1 STATUS in (0.5 s, 1.5 s]
    assert [f.seq for f in frames] == [0, 1, 2, 3, 9]
    assert frames[-1].flags & wire.FLAG_DROPPED_BEFORE


def test_calm_longer_than_ticks_diff_range():
    """An edge 15 min after the previous one is counted, at the right time, with no bogus period."""
    out = bytearray()
    emu = EmulatedBridge(lambda b: out.extend(b) or len(b))
    edges = [1_000_000, 1_100_000, 901_000_000, 901_200_000]
    emu.add_edges(0, edges)
    emu.advance_to(902_000_000)
    s = [f for f in wire.StreamDecoder().feed(bytes(out)) if f.msg_type == wire.SAMPLE]
    by_t = {f.t_us: f.fields["anemo"] for f in s}
    assert by_t[1_250_000] == (2, 1_100_000, 100_000)
    assert by_t[901_000_000] == (3, 901_000_000, 0)  # the period was forgotten during the calm
    assert by_t[902_000_000] == (4, 901_200_000, 200_000)


@pytest.mark.parametrize("spacing,ticks_start", [(997, 0), (400, (1 << 30) - 300_000)])
def test_isr_never_allocates_under_micropython(spacing, ticks_start):
    """The ISR runs with the heap locked (MemoryError on any allocation), across a ticks wrap."""
    n = 2000
    r = subprocess.run(
        [
            tools.micropython(),
            str(ROOT / "sim_devices/upy/isr_check.py"),
            str(tools.board_lib()),
            str(n),
            str(spacing),
            str(ticks_start),
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    got = tuple(map(int, r.stdout.split()))
    # the same lockout worked out here, on unwrapped times
    accepted = []
    for i in range(n):
        t = i * spacing
        if not accepted or t - accepted[-1] >= 1500:
            accepted.append(t)
    want = (
        len(accepted),
        (ticks_start + accepted[-1]) % TICKS_PERIOD,
        accepted[-1] - accepted[-2],
        n - len(accepted),
    )
    assert got == want
