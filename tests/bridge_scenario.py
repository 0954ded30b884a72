"""Shared pulse-train scenario for the bridge end-to-end tests: edge schedules and the truth."""

from __future__ import annotations

import bisect
import os
import select
import time

import pytest
import serial
from forcemap.host.decode.pulses import PulseTracker
from forcemap.protocol import wire

ANEMO_HZ = 10.0
WHEEL_HZ = (3.7, 5.3, 8.9, 13.1)
RATES = (ANEMO_HZ, *WHEEL_HZ)


def true_edges(rate_hz: float, t_end_us: int, offset_us: int) -> list[int]:
    """Edge times of a constant-rate train (integer us), first edge at ``offset_us``."""
    period = 1e6 / rate_hz
    n = int((t_end_us - offset_us) / period) + 1
    return [
        offset_us + int(round(k * period))
        for k in range(n)
        if offset_us + round(k * period) < t_end_us
    ]


def count_in(edges: list[int], t_a: int, t_b: int) -> int:
    """Edges e with t_a < e <= t_b."""
    return bisect.bisect_right(edges, t_b) - bisect.bisect_right(edges, t_a)


def last_at(edges: list[int], t: int) -> int | None:
    i = bisect.bisect_right(edges, t)
    return edges[i - 1] if i else None


class Host:
    """The host side of the pty: pyserial, the streaming decoder and the pulse tracker."""

    def __init__(self, path: str):
        self.ser = serial.Serial(path, timeout=0)
        self.dec = wire.StreamDecoder()
        self.tracker = PulseTracker()
        self.frames: list[wire.Frame] = []
        self.rates: dict[int, list] = {}  # boot_id -> last ChannelRate list

    def read_available(self, wait_s: float = 0.0) -> int:
        """Read what has arrived, first waiting up to ``wait_s`` for anything to arrive."""
        if wait_s:
            select.select([self.ser.fileno()], [], [], wait_s)
        n = self.ser.in_waiting
        data = self.ser.read(n) if n else b""
        for f in self.dec.feed(data):
            self.frames.append(f)
            r = self.tracker.update(f)
            if r:
                self.rates[f.boot_id] = r
        return len(data)

    def drain(self, idle_s: float = 0.3, done=lambda: True) -> None:
        """Read until nothing arrives for ``idle_s`` and ``done()`` is true."""
        self.ser.timeout = idle_s
        while True:
            data = self.ser.read(1 << 16)
            if data:
                for f in self.dec.feed(data):
                    self.frames.append(f)
                    r = self.tracker.update(f)
                    if r:
                        self.rates[f.boot_id] = r
            elif done():
                return
            else:
                time.sleep(0.01)

    def close(self) -> None:
        self.ser.close()


def check_boot(
    samples: list[wire.Frame], boot_us: int, edges: list[list[int]], totals, rates
) -> None:
    """Exact pulse totals, last-edge times and rates for one boot's SAMPLE frames."""
    first, last = samples[0], samples[-1]
    for ch in range(5):
        want = count_in(edges[ch], boot_us + first.t_us, boot_us + last.t_us)
        assert totals[ch] == want, (ch, totals[ch], want)
    for f in samples:
        chans = [f.fields["anemo"], *f.fields["wheels"]]
        for ch in range(5):
            e = last_at(edges[ch], boot_us + f.t_us)
            if e is not None and e >= boot_us:
                assert boot_us + chans[ch][1] == e, (ch, f)
    for ch in range(5):
        assert rates[ch].rate_hz == pytest.approx(RATES[ch], rel=2e-4)


def openpty_raw():
    import tty

    m, s = os.openpty()
    tty.setraw(s)
    return m, s
