"""Watchdog that lets the REPL live: the hardware WDT is fed from a timer only while the main loop
keeps calling ``feed()``. After Ctrl-C (mpremote interrupting the bridge to flash it) ``hold()``
keeps the board alive at the REPL; rp2's WDT cannot be stopped once started.
"""


class LoopWatchdog:
    """``wdt``: has ``feed()``. ``timer``: a ``machine.Timer``. ``clock``: ``ticks_ms``/``ticks_diff``."""

    def __init__(self, wdt, timer, clock, loop_timeout_ms=3000, period_ms=500):
        self._wdt = wdt
        self._ms = clock.ticks_ms
        self._diff = clock.ticks_diff
        self._timeout = loop_timeout_ms
        self._last = self._ms()
        self._held = False
        self._tick_cb = self._tick
        timer.init(period=period_ms, mode=timer.PERIODIC, callback=self._tick_cb)

    def feed(self):
        """The main loop is alive."""
        self._last = self._ms()

    def hold(self):
        """Keep feeding whatever the main loop does (for the REPL after an interrupt)."""
        self._held = True

    def _tick(self, _timer):
        if self._held or self._diff(self._ms(), self._last) < self._timeout:
            self._wdt.feed()
