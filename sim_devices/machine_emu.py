"""A ``machine``/``time`` stand-in for running the bridge firmware on CPython.

Virtual time only: nothing here reads the host clock. ``VirtualClock`` is both the ``time`` module
the firmware sees (``ticks_us`` wrapping at 2**30 as on rp2/esp32, ``ticks_diff``, ``ticks_add``,
``sleep_us``) and the timeline the emulator advances. Pins fire their IRQ handler when the
emulator calls ``fire()``; ``ADC.read_u16`` quantises a settable voltage like the RP2040.
"""

from __future__ import annotations

import random

TICKS_BITS = 30
TICKS_PERIOD = 1 << TICKS_BITS
TICKS_MAX = TICKS_PERIOD - 1
TICKS_HALF = TICKS_PERIOD // 2

# machine.reset_cause() values (rp2 and esp32 numbering)
PWRON_RESET = 1
HARD_RESET = 2
WDT_RESET = 3
DEEPSLEEP_RESET = 4
SOFT_RESET = 5


class VirtualClock:
    """Virtual microseconds. ``now`` is the emulator's timeline (never wraps); the firmware sees
    ``ticks_us() = (ticks_start + now - boot) mod 2**30``.
    """

    def __init__(self, now: int = 0, ticks_start: int = 0):
        self.now = now
        self.boot = now
        self.ticks_start = ticks_start & TICKS_MAX

    def restart(self, ticks_start: int | None = None) -> None:
        """Board reset: ticks restart from ``ticks_start`` at the current time."""
        self.boot = self.now
        if ticks_start is not None:
            self.ticks_start = ticks_start & TICKS_MAX

    def ticks_us(self) -> int:
        return (self.ticks_start + self.now - self.boot) & TICKS_MAX

    def ticks_ms(self) -> int:
        return ((self.ticks_start + self.now - self.boot) // 1000) & TICKS_MAX

    @staticmethod
    def ticks_diff(a: int, b: int) -> int:
        return ((a - b + TICKS_HALF) & TICKS_MAX) - TICKS_HALF

    @staticmethod
    def ticks_add(t: int, delta: int) -> int:
        return (t + delta) & TICKS_MAX

    def sleep_us(self, us: int) -> None:
        self.now += max(0, int(us))

    def sleep_ms(self, ms: int) -> None:
        self.now += max(0, int(ms)) * 1000


class Pin:
    """An input pin. ``fire()`` is one falling edge: counters see it, then the IRQ handler runs."""

    IN = 0
    OUT = 1
    PULL_UP = 1
    PULL_DOWN = 2
    IRQ_FALLING = 4
    IRQ_RISING = 8

    def __init__(self, id, mode=IN, pull=None):
        self.id = id
        self._level = 1
        self._handler = None
        self.trigger = 0
        self.hard = False
        self._counters: list[Counter] = []

    def irq(self, handler=None, trigger=IRQ_FALLING | IRQ_RISING, hard=False):
        self._handler = handler
        self.trigger = trigger
        self.hard = hard

    def value(self, v=None):
        if v is None:
            return self._level
        self._level = 1 if v else 0
        return None

    def fire(self) -> None:
        for c in self._counters:
            c.count += 1
        h = self._handler
        if h is not None:
            h(self)


class Counter:
    """``machine.Counter`` (esp32 PCNT): counts edges on ``src`` with no Python per edge."""

    RISING = 1
    FALLING = 2
    UP = 1
    DOWN = -1

    def __init__(self, id, src=None, edge=RISING, filter_ns=0):
        self.id = id
        self.count = 0
        self.src = src
        if src is not None:
            src._counters.append(self)

    def value(self, v=None):
        c = self.count
        if v is not None:
            self.count = v
        return c


class ADC:
    """``read_u16`` of a settable voltage: Gaussian noise (``noise_v`` volts RMS), 12-bit
    quantisation against ``vref``, scaled to 16 bits as rp2 does (``raw << 4 | raw >> 8``).
    """

    def __init__(self, pin=None, *, vref: float = 3.3, noise_v: float = 0.002, seed: int = 0):
        self.vref = vref
        self.noise_v = noise_v
        self.volts = 0.0
        self._rng = random.Random(seed)

    def set_voltage(self, volts: float) -> None:
        self.volts = volts

    def read_u16(self) -> int:
        v = self.volts
        if self.noise_v:
            v += self._rng.gauss(0.0, self.noise_v)
        raw = round(v / self.vref * 4095)
        raw = 0 if raw < 0 else 4095 if raw > 4095 else raw
        return (raw << 4) | (raw >> 8)


class WDT:
    """``machine.WDT``: ``expired(now_us)`` is True when not fed for ``timeout`` ms."""

    def __init__(self, clock: VirtualClock, id=0, timeout: int = 5000):
        self._clock = clock
        self.timeout_us = timeout * 1000
        self.last_feed = clock.now
        self.feeds = 0

    def feed(self) -> None:
        self.last_feed = self._clock.now
        self.feeds += 1

    def expired(self) -> bool:
        return self._clock.now - self.last_feed > self.timeout_us


class Machine:
    """What the emulated board's ``machine`` module would offer, bound to one clock."""

    PWRON_RESET = PWRON_RESET
    HARD_RESET = HARD_RESET
    WDT_RESET = WDT_RESET
    SOFT_RESET = SOFT_RESET
    Pin = Pin
    ADC = ADC
    Counter = Counter

    def __init__(self, clock: VirtualClock, cause: int = PWRON_RESET):
        self.clock = clock
        self.cause = cause

    def reset_cause(self) -> int:
        return self.cause

    def WDT(self, id=0, timeout: int = 5000) -> WDT:  # noqa: N802 - machine's name
        return WDT(self.clock, id, timeout)
