"""The simulator's stimulus helpers and the emulated USB-CDC pty."""

from __future__ import annotations

import os
import random
import time

import pytest
import serial
from forcemap.host.decode.vane import decode_vane
from forcemap.host.vessel.geodesy import wrap_to_180
from forcemap.sim_devices.bridge_emu import add_bounce, pulse_times, vane_resistance, vane_voltage
from forcemap.sim_devices.usb_cdc import UsbCdc
from hypothesis import given, settings
from hypothesis import strategies as st


@given(
    hz=st.floats(0.05, 200.0),
    cuts=st.lists(st.integers(1, 9_999_999), max_size=8, unique=True),
    phase=st.floats(0.0, 1.0),
)
@settings(max_examples=200, deadline=None)
def test_pulse_times_chunks_join_seamlessly(hz, cuts, phase):
    whole, end_phase = pulse_times(hz, 0, 10_000_000, phase)
    bounds = [0, *sorted(cuts), 10_000_000]
    parts = []
    p = phase
    for a, b in zip(bounds, bounds[1:], strict=False):
        times, p = pulse_times(hz, a, b, p)
        parts += times
    assert len(parts) == len(whole)
    assert all(abs(x - y) <= 1 for x, y in zip(parts, whole, strict=False))
    assert p == pytest.approx(end_phase, abs=1e-6)


def test_pulse_times_piecewise_and_function():
    times, phase = pulse_times([(0, 2.0), (1_000_000, 0.0), (3_000_000, 4.0)], 0, 4_000_000)
    # the edge due at 1 s (end of the 2 Hz stretch) comes when the train moves again at 3 s
    assert times == [500_000, 3_000_000, 3_250_000, 3_500_000, 3_750_000]
    assert phase == 1.0  # the next edge is due right at 4 s
    fn_times, _ = pulse_times(lambda t: 5.0, 0, 1_000_000)
    assert fn_times == [200_000, 400_000, 600_000, 800_000]


def test_add_bounce():
    assert add_bounce([1000, 5000], bounce_us=300, n=2) == [1000, 1150, 1300, 5000, 5150, 5300]
    b = add_bounce([1000], bounce_us=300, n=3, rng=random.Random(1))
    assert len(b) == 4 and b[0] == 1000 and all(1000 < x <= 1300 for x in b[1:])


@pytest.mark.parametrize("deg", [i * 22.5 for i in range(16)] + [10.0, -100.0, 359.0])
def test_vane_voltage_round_trip_with_offset(deg):
    v = vane_voltage(deg, mounting_offset=30.0)
    raw = round(v / 3.3 * 65535)
    want = round((deg - 30.0) / 22.5) * 22.5 + 30.0
    assert decode_vane(raw, mounting_offset=30.0) == wrap_to_180(want)


def test_in_between_positions_are_parallel_pairs():
    assert vane_resistance(22.5) == pytest.approx(6_570, rel=0.001)
    assert vane_resistance(337.5) == pytest.approx(21_880, rel=0.001)


def settle(port, n):
    """Wait (bounded) for the pty to move written bytes to the slave side."""
    for _ in range(2000):
        if port.unread() >= n:
            return
        time.sleep(0.001)


def test_usb_cdc_pty_symlink_and_backpressure(tmp_path):
    link = str(tmp_path / "ports" / "bridge")
    with UsbCdc(link, host_buffer=0) as port:
        assert os.path.realpath(link) == port.slave_path
        host = serial.Serial(link, timeout=0.5)
        assert port.write(bytes(range(200))) == 200
        settle(port, 200)
        assert port.writable()
        assert port.write(bytes(100)) is None  # 56 bytes fit: the rest is cut, as after a timeout
        settle(port, 256)
        assert not port.writable() and port.write(b"\x01") is None
        got = host.read(256)
        assert got == bytes(range(200)) + bytes(56)
        assert port.writable() and port.write(b"\x00\xff\x00") == 3
        assert host.read(3) == b"\x00\xff\x00"
        host.close()
    assert not os.path.lexists(link)
