"""The bridge loop: HELLO at boot, SAMPLE every sample period, STATUS every second.

Everything the board provides is injected, so the same code runs on a board, under the CPython
stand-in (``forcemap.sim_devices.machine_emu``) and under the unix-port MicroPython harness:

    bridge = Bridge(counters, Vane(adc), sys.stdout.buffer, time, boot_id=..., reset_cause=...)
    bridge.start()
    run(bridge, time.sleep_us)

Device time is a u64 of microseconds since boot, extended from ``ticks_us`` with ``ticks_diff`` on
every ``poll()``; it is never a float. When the output is not writable (the host is not reading and
the USB-CDC FIFO is full) a frame is dropped and counted instead of stalling sampling, and the next
frame sent carries ``wire.FLAG_DROPPED_BEFORE``.
"""

from forcemap.firmware_bridge import config
from forcemap.protocol import wire


class Bridge:
    """``counters``: five pulse inputs (anemometer, wheels 1-4) with ``snapshot()``, ``forget_edge()``
    and ``rejects()``. ``vane``: has ``read()``. ``out``: has ``write(bytes) -> int|None``.
    ``clock``: ``ticks_us``/``ticks_diff`` (the ``time`` module on a board). ``writable()``: False
    when a write would block. ``wdt``: has ``feed()``. ``mem_free()``: free heap bytes.
    """

    def __init__(
        self,
        counters,
        vane,
        out,
        clock,
        boot_id,
        reset_cause=0,
        writable=None,
        wdt=None,
        mem_free=None,
        board="nano_rp2040",
        sample_period_us=config.SAMPLE_PERIOD_US,
        status_period_us=config.STATUS_PERIOD_US,
        anemo_hz_per_mps=config.ANEMO_HZ_PER_MPS,
        wheel_ppm=config.WHEEL_PULSES_PER_M,
    ):
        self._counters = counters
        self._vane = vane
        self._out = out
        self._ticks = clock.ticks_us
        self._diff = clock.ticks_diff
        self._writable = writable
        self._wdt = wdt
        self._mem_free = mem_free
        self.boot_id = boot_id & 0xFFFFFFFF
        self.reset_cause = reset_cause
        self.board = board
        self.sample_period_us = sample_period_us
        self.status_period_us = status_period_us
        self.anemo_hz_per_mps = anemo_hz_per_mps
        self.wheel_ppm = wheel_ppm
        self.seq = 0
        self.t_us = 0
        self._last_ticks = self._ticks()
        self._next_sample = 0
        self._next_status = status_period_us
        self._dropped = False
        n = len(counters)
        self._seen = [0] * n  # count at the previous sample
        self._edge_t = [0] * n  # device time of each channel's last edge, 0 = none yet
        self.frames_sent = 0
        self.write_timeouts = 0
        self.frames_dropped = 0
        self.loop_overruns = 0

    def _advance(self):
        now = self._ticks()
        self.t_us += self._diff(now, self._last_ticks)
        self._last_ticks = now
        return now

    def _send(self, msg_type, payload):
        flags = wire.FLAG_DROPPED_BEFORE if self._dropped else 0
        frame = wire.encode(msg_type, self.boot_id, self.seq, self.t_us, payload, flags)
        self.seq = (self.seq + 1) & 0xFFFFFFFF
        if self._writable is not None and not self._writable():
            self.frames_dropped += 1
            self._dropped = True
            return False
        n = self._out.write(frame)
        if n is None or n < len(frame):
            self.write_timeouts += 1
            self._dropped = True
            return False
        self.frames_sent += 1
        self._dropped = False
        return True

    def start(self):
        """Send HELLO. Call once after construction, before ``poll()``."""
        self._advance()
        self._send(
            wire.HELLO,
            wire.pack_hello(
                config.FW_VERSION,
                self.reset_cause,
                self.sample_period_us,
                config.TICKS_BITS,
                self.anemo_hz_per_mps,
                self.wheel_ppm,
                config.BOARDS[self.board]["name"],
                config.pin_map(self.board),
            ),
        )

    def sample(self):
        """Build and send one SAMPLE frame now."""
        snaps = [c.snapshot() for c in self._counters]
        vane_raw = self._vane.read()
        now = self._advance()
        t = self.t_us
        chans = []
        for i in range(len(snaps)):
            count, last, period = snaps[i]
            if count != self._seen[i]:
                # an edge since the last sample, so well inside ticks_diff's range
                self._edge_t[i] = t - self._diff(now, last)
                self._seen[i] = count
            elif self._edge_t[i] and t - self._edge_t[i] > config.STALE_EDGE_US:
                self._counters[i].forget_edge(count)
            chans.append((count, self._edge_t[i], period))
        return self._send(wire.SAMPLE, wire.pack_sample(vane_raw, chans))

    def status(self):
        """Build and send one STATUS frame now."""
        rejects = 0
        for c in self._counters:
            rejects += c.rejects()
        mem = self._mem_free() if self._mem_free is not None else 0
        return self._send(
            wire.STATUS,
            wire.pack_status(
                (
                    self.frames_sent & 0xFFFFFFFF,
                    self.write_timeouts & 0xFFFFFFFF,
                    self.frames_dropped & 0xFFFFFFFF,
                    mem & 0xFFFFFFFF,
                    rejects & 0xFFFFFFFF,
                    self.loop_overruns & 0xFFFFFFFF,
                )
            ),
        )

    def poll(self):
        """Do whatever is due; return the microseconds until something is due next (>= 0)."""
        self._advance()
        if self.t_us >= self._next_sample:
            self.sample()
            self._next_sample += self.sample_period_us
            if self._next_sample <= self.t_us:
                self.loop_overruns += 1
                self._next_sample = self.t_us + self.sample_period_us
        if self.t_us >= self._next_status:
            self.status()
            self._next_status += self.status_period_us
            if self._next_status <= self.t_us:
                self._next_status = self.t_us + self.status_period_us
        if self._wdt is not None:
            self._wdt.feed()
        wait = min(self._next_sample, self._next_status) - self.t_us
        return wait if wait > 0 else 0


def run(bridge, sleep_us, running=None):
    """The main loop: poll, then sleep until the next thing is due. ``running()`` False stops it."""
    bridge.start()
    while running is None or running():
        wait = bridge.poll()
        if wait:
            sleep_us(wait)
