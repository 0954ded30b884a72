"""Runs the board entry point ``firmware_bridge/main.py`` under the unix-port MicroPython with fake
``machine`` and ``time`` modules put in ``sys.modules``, for ``N`` main-loop sleeps; frames go to
stdout. Checks that main.py wires the real modules together as a board would.

    micropython sim_devices/upy/main_smoke.py LIB BOARD_MACHINE_NAME N_SLEEPS [kbd]

With ``kbd`` the last sleep raises KeyboardInterrupt (mpremote's Ctrl-C) instead of stopping, and
the watchdog timer is then run 10 s later to show it still feeds the WDT at the REPL.
"""

import os
import sys

LIB = sys.argv[1]  # the board's files as sources: main.py and forcemap/...
sys.path.insert(0, LIB)

MASK = (1 << 30) - 1


class FakeTime:
    def __init__(self, n_sleeps):
        self.now = 0
        self.left = n_sleeps
        self.edges = []

    def ticks_us(self):
        return self.now & MASK

    def ticks_ms(self):
        return (self.now // 1000) & MASK

    def ticks_diff(self, a, b):
        return ((a - b + (1 << 29)) & MASK) - (1 << 29)

    def ticks_add(self, t, d):
        return (t + d) & MASK

    def sleep_us(self, us):
        self.left -= 1
        if self.left < 0:
            raise KeyboardInterrupt if KBD else SystemExit
        end = self.now + us
        while self.edges and self.edges[0][0] <= end:
            t, pin = self.edges.pop(0)
            self.now = t
            pin.handler(pin)
        self.now = end


class Pin:
    IN = 0
    PULL_UP = 1
    IRQ_FALLING = 4
    made = {}

    def __init__(self, name, mode=0, pull=None):
        self.name = name
        self.handler = None
        Pin.made[name] = self

    def irq(self, handler=None, trigger=0, hard=False):
        self.handler = handler
        Pin.hard = hard


class ADC:
    ATTN_11DB = 3

    def __init__(self, pin, atten=None):
        ADC.atten = atten

    def read_u16(self):
        return 29527


class Counter:
    FALLING = 2
    units = []

    def __init__(self, unit, src, edge=0):
        Counter.units.append((unit, src.name))

    def value(self):
        return 0


class WDT:
    def __init__(self, timeout=0):
        self.feeds = 0
        WDT.last = self

    def feed(self):
        self.feeds += 1


class Timer:
    PERIODIC = 1

    def __init__(self, id):
        self.id = id

    def init(self, period=0, mode=0, callback=None):
        Timer.cb = callback
        Timer.last = self


class Machine:
    Pin = Pin
    ADC = ADC
    WDT = WDT
    Timer = Timer

    def reset_cause(self):
        return 3


class FakeOs:
    def __init__(self, machine_name):
        self._m = machine_name

    def uname(self):
        class U:
            pass

        u = U()
        u.machine = self._m
        return u

    def urandom(self, n):
        return os.urandom(n)


class FakeMicropython:
    emergency = 0

    def alloc_emergency_exception_buf(self, n):
        FakeMicropython.emergency = n


board = sys.argv[2]
KBD = len(sys.argv) > 4 and sys.argv[4] == "kbd"
fake_machine = Machine()
if "ESP32" in board:
    fake_machine.Counter = Counter
ft = FakeTime(int(sys.argv[3]))
sys.modules["machine"] = fake_machine
sys.modules["time"] = ft
sys.modules["os"] = FakeOs(board)
sys.modules["micropython"] = FakeMicropython()
Pin.made.clear()
interrupted = False
try:
    import main  # noqa: F401  (firmware_bridge/main.py, found through sys.path above)
except SystemExit:
    pass
except KeyboardInterrupt:
    interrupted = True
feeds_before = WDT.last.feeds
ft.now += 10_000_000
Timer.cb(Timer.last)
Timer.cb(Timer.last)
info = (
    f"pins={len(Pin.made)} hard={Pin.hard} counters={len(Counter.units)} atten={ADC.atten} "
    f"timer={Timer.last.id} emergency={FakeMicropython.emergency} interrupted={interrupted} "
    f"repl_feeds={WDT.last.feeds - feeds_before}\n"
)
sys.stderr.write(info)
