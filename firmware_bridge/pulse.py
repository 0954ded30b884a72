"""Pulse inputs: edge counting by IRQ with a bounce lockout, or by a hardware counter.

The ISR never allocates: its state lives in a pre-allocated ``array`` and every value stays a small
int (ticks are below 2**30 on the boards, counts are wrapped to ``wire.COUNT_MOD``).

    from machine import Pin
    import time
    anemo = PulseCounter(Pin("D2", Pin.IN, Pin.PULL_UP), time, lockout_us=1500)
    count, last_edge_ticks, period_us = anemo.snapshot()
"""

from array import array

from forcemap.protocol import wire

_MASK = wire.COUNT_MOD - 1
# state slots
_COUNT = 0
_LAST = 1  # ticks_us of the last accepted edge
_PERIOD = 2  # us between the last two accepted edges, 0 = unknown
_HAVE = 3  # 1 once an edge was accepted (and not forgotten since)
_REJECTS = 4  # edges inside the lockout


class PulseCounter:
    """Counts falling edges on ``pin`` from its IRQ, ignoring edges within ``lockout_us`` of the last.

    ``clock`` provides ``ticks_us`` and ``ticks_diff`` (the ``time`` module on a board).
    ``hard`` asks for a hard IRQ where the port supports it (rp2); esp32 only has soft IRQs.
    """

    def __init__(self, pin, clock, lockout_us=1500, hard=False, trigger=None):
        self._ticks = clock.ticks_us
        self._diff = clock.ticks_diff
        self._lockout = lockout_us
        self._st = array("i", (0, 0, 0, 0, 0))
        self.pin = pin
        if trigger is None:
            trigger = pin.IRQ_FALLING
        if hard:
            pin.irq(handler=self._isr, trigger=trigger, hard=True)
        else:
            pin.irq(handler=self._isr, trigger=trigger)

    def _isr(self, pin):
        now = self._ticks()
        st = self._st
        if st[_HAVE]:
            d = self._diff(now, st[_LAST])
            if d < self._lockout:
                r = st[_REJECTS]
                st[_REJECTS] = r + 1 if r < _MASK else 0
                return
            st[_PERIOD] = d
        else:
            st[_HAVE] = 1
        st[_LAST] = now
        # c + 1 == 2**30 would be a heap-allocated int on the boards: wrap before it exists
        c = st[_COUNT]
        st[_COUNT] = c + 1 if c < _MASK else 0

    def snapshot(self):
        """(count, ticks of the last edge, period in us), consistent even if an edge fires meanwhile."""
        st = self._st
        while True:
            c = st[_COUNT]
            last = st[_LAST]
            period = st[_PERIOD]
            if st[_COUNT] == c:
                return c, last, period

    def forget_edge(self, count):
        """Called by the main loop when the last edge is old: the next edge starts a new period.

        Keeps ``ticks_diff`` inside its valid range. Does nothing if an edge arrived since ``count``.
        """
        st = self._st
        if st[_COUNT] == count:
            st[_HAVE] = 0
            st[_PERIOD] = 0

    def rejects(self):
        return self._st[_REJECTS]


class CounterPulses(PulseCounter):
    """Counts with a hardware counter (``machine.Counter`` on esp32, no per-edge Python) for inputs
    that do not bounce; a soft IRQ on the same pin records edge times for the period.

    ``counter`` is an object with ``value()``. The count is exact; the edge time is best effort,
    as scheduled IRQs can be late or dropped under load.
    """

    def __init__(self, pin, clock, counter, trigger=None):
        self._counter = counter
        super().__init__(pin, clock, lockout_us=0, hard=False, trigger=trigger)

    def snapshot(self):
        st = self._st
        return self._counter.value() & _MASK, st[_LAST], st[_PERIOD]

    def forget_edge(self, count):
        if self._counter.value() & _MASK == count:
            self._st[_HAVE] = 0
            self._st[_PERIOD] = 0
