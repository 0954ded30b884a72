"""Runs the bridge firmware under the unix-port MicroPython on fake pins, ADC and a virtual clock.

    micropython sim_devices/upy/bridge_harness.py LIB SCHEDULE

LIB holds the board's files as sources (``forcemap.host.cli.bridge.source_tree``).

Frames go to stdout (connect it to a pty and read the other end with pyserial). Time is virtual:
``ticks_us`` wraps at 2**30 as on the boards, and sleeping fires the scheduled edges in order.
The schedule is a small text file, one directive per line (times in us, rates in mHz, all ints):

    board nano_rp2040            # or nano_esp32 (wheels on fake machine.Counter units)
    seed 7                       # boot ids
    ticks_start 1043741824       # ticks_us() at each boot
    end 90000000                 # stop at this time
    rate CH MHZ START STOP [BOUNCE_US N]
                                 # edge k at START + k*10**9//MHZ while < STOP, plus N bounce
                                 # edges at + BOUNCE_US*(j+1)//N
    vane RAW                     # read_u16 value of the vane (with +-8 counts of noise)
    deaf T0 T1                   # the host does not read: the output is not writable
    reset T CAUSE                # board reset at T with machine.reset_cause() = CAUSE
"""

import sys

sys.path.insert(0, sys.argv[1])

import machine  # noqa: E402
from forcemap.firmware_bridge import config  # noqa: E402
from forcemap.firmware_bridge.bridge import Bridge, run  # noqa: E402
from forcemap.firmware_bridge.pulse import CounterPulses, PulseCounter  # noqa: E402
from forcemap.firmware_bridge.vane import Vane  # noqa: E402

MASK = (1 << 30) - 1
HALF = 1 << 29


class Clock:
    """Virtual us: ``now`` is the timeline; the firmware sees ticks that restart at each boot."""

    def __init__(self, ticks_start):
        self.now = 0
        self.boot = 0
        self.ticks_start = ticks_start
        self.events = None

    def ticks_us(self):
        return (self.ticks_start + self.now - self.boot) & MASK

    def ticks_ms(self):
        return ((self.ticks_start + self.now - self.boot) // 1000) & MASK

    def ticks_diff(self, a, b):
        return ((a - b + HALF) & MASK) - HALF

    def ticks_add(self, t, d):
        return (t + d) & MASK

    def sleep_us(self, us):
        self.events.run_until(self.now + us)


class FakePin(machine.PinBase):
    IN = 0
    PULL_UP = 1
    IRQ_FALLING = 4
    IRQ_RISING = 8

    def __init__(self, name):
        self.name = name
        self.handler = None
        self.counters = []
        self.level = 1

    def value(self, v=None):
        if v is None:
            return self.level
        self.level = v

    def irq(self, handler=None, trigger=12, hard=False):
        self.handler = handler

    def fire(self):
        for c in self.counters:
            c.count += 1
        if self.handler is not None:
            self.handler(self)


class FakeCounter:
    FALLING = 2

    def __init__(self, unit, src, edge=2):
        self.count = 0
        src.counters.append(self)

    def value(self):
        return self.count


class FakeADC:
    def __init__(self):
        self.raw = 32768
        self._x = 12345

    def read_u16(self):
        self._x = (self._x * 1103515245 + 12345) & 0x7FFFFFFF
        v = self.raw + (self._x >> 16) % 17 - 8
        return 0 if v < 0 else 65535 if v > 65535 else v


class Train:
    """One channel's deterministic edges, generated lazily."""

    def __init__(self, ch, mhz, start, stop, bounce_us, n_bounce):
        self.ch = ch
        self.mhz = mhz
        self.start = start
        self.stop = stop
        self.bounce_us = bounce_us
        self.n_bounce = n_bounce
        self.k = 0
        self.j = 0
        self.next = 0
        self._base = start
        self._advance()

    def _advance(self):
        if self.j < self.n_bounce and self.k > 0:
            self.j += 1
            self.next = self._base + self.bounce_us * self.j // self.n_bounce
            return
        self.j = 0
        t = self.start + self.k * 1_000_000_000 // self.mhz
        self.k += 1
        self._base = t
        self.next = t if t < self.stop else None

    def pop(self):
        t = self.next
        self._advance()
        return t


class Events:
    def __init__(self, clock, trains, stop_at):
        self.clock = clock
        self.trains = trains
        self.pins = None
        self.stop_at = stop_at  # next reset or end: sleeping stops there

    def run_until(self, t):
        if t > self.stop_at:
            t = self.stop_at
        clock = self.clock
        trains = self.trains
        pins = self.pins
        while True:
            best = None
            bt = t + 1
            for tr in trains:
                n = tr.next
                if n is not None and n < bt:
                    best = tr
                    bt = n
            if best is None:
                break
            clock.now = bt
            best.pop()
            pins[best.ch].fire()
        clock.now = t


def parse(path):
    s = {"board": "nano_rp2040", "seed": 1, "ticks_start": 0, "end": 10_000_000, "rates": [],
         "vane": 32768, "deaf": [], "resets": []}  # fmt: skip
    with open(path) as f:
        for line in f:
            w = line.split("#")[0].split()
            if not w:
                continue
            k = w[0]
            if k == "board":
                s["board"] = w[1]
            elif k in ("seed", "ticks_start", "end", "vane"):
                s[k] = int(w[1])
            elif k == "rate":
                v = [int(x) for x in w[1:]]
                if len(v) == 4:
                    v += [0, 0]
                s["rates"].append(v)
            elif k == "deaf":
                s["deaf"].append((int(w[1]), int(w[2])))
            elif k == "reset":
                s["resets"].append((int(w[1]), int(w[2])))
    return s


def main(path):
    s = parse(path)
    clock = Clock(s["ticks_start"])
    trains = [Train(*r) for r in s["rates"]]
    stops = sorted(s["resets"]) + [(s["end"], None)]
    events = Events(clock, trains, stops[0][0])
    clock.events = events
    adc = FakeADC()
    adc.raw = s["vane"]
    out = sys.stdout.buffer
    deaf = s["deaf"]

    def writable():
        for a, b in deaf:
            if a <= clock.now < b:
                return False
        return True

    seed = s["seed"]
    cause = 1
    b = config.BOARDS[s["board"]]
    for stop, next_cause in stops:
        events.stop_at = stop
        clock.boot = clock.now
        pins = [FakePin(name) for name in b["pulse_pins"]]
        events.pins = pins
        counters = []
        for i in range(len(pins)):
            if i in b["hw_counter"]:
                hw = FakeCounter(b["hw_counter"].index(i), pins[i])
                counters.append(CounterPulses(pins[i], clock, hw))
            else:
                counters.append(PulseCounter(pins[i], clock, config.LOCKOUT_US, hard=b["hard_irq"]))
        seed = (seed * 1103515245 + 12345) & 0xFFFFFFFF
        bridge = Bridge(
            counters,
            Vane(adc, config.VANE_SAMPLES),
            out,
            clock,
            boot_id=seed,
            reset_cause=cause,
            writable=writable,
            mem_free=lambda: 100_000,
            board=s["board"],
        )
        run(bridge, clock.sleep_us, lambda: clock.now < stop)  # noqa: B023 - stop of this boot
        cause = next_cause


if __name__ == "__main__":
    main(sys.argv[2])
