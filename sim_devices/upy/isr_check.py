"""Runs the pulse ISR under the unix-port MicroPython with the heap locked: any allocation in the
ISR raises MemoryError. Prints ``count ticks period rejects``.

    micropython sim_devices/upy/isr_check.py LIB N_EDGES SPACING_US TICKS_START
"""

import sys

sys.path.insert(0, sys.argv[1])

import micropython  # noqa: E402
from forcemap.firmware_bridge.pulse import PulseCounter  # noqa: E402

MASK = 0x3FFFFFFF


class Clock:
    def __init__(self):
        self.t = 0

    def ticks_us(self):
        return self.t

    def ticks_diff(self, a, b):
        return ((a - b + 0x20000000) & MASK) - 0x20000000


class Pin:
    IRQ_FALLING = 4

    def irq(self, handler=None, trigger=0, hard=False):
        self.handler = handler


def main():
    n = int(sys.argv[2])
    spacing = int(sys.argv[3])
    start = int(sys.argv[4])
    ticks = [(start + i * spacing) & MASK for i in range(n)]
    clock = Clock()
    pin = Pin()
    pc = PulseCounter(pin, clock, 1500, hard=True)
    isr = pin.handler
    micropython.heap_lock()
    try:
        for t in ticks:
            clock.t = t
            isr(pin)
    finally:
        micropython.heap_unlock()
    c, last, period = pc.snapshot()
    print(c, last, period, pc.rejects())


main()
