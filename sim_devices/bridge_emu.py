"""The real bridge firmware on emulated pins, for tests and the simulator.

``EmulatedBridge`` builds ``firmware_bridge`` objects on ``machine_emu`` pins, an ADC and a virtual
clock, fires pulse edges at their exact device times and runs the firmware's ``poll()`` when it asked
to be woken. Frames go to ``write``; nothing here reads the host clock, so it runs as fast as Python.

    emu = EmulatedBridge(port.write, writable=port.writable)
    times, phase = pulse_times(10.0, 0, 1_000_000)
    emu.add_edges(0, add_bounce(times, rng=random.Random(1)))
    emu.set_vane_voltage(vane_voltage(45.0))
    emu.advance_to(1_000_000)

Timeline: ``now_us``, ``add_edges`` and ``advance_to`` use the emulator's timeline, which never goes
back. Frames carry the firmware's device time, microseconds since its boot: timeline = ``boot_us`` +
``frame.t_us``. After ``reset()`` the firmware's time, counts and ticks restart.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Iterable, Sequence

from forcemap.firmware_bridge import config
from forcemap.firmware_bridge.bridge import Bridge
from forcemap.firmware_bridge.pulse import CounterPulses, PulseCounter
from forcemap.firmware_bridge.vane import Vane
from forcemap.sim_devices import machine_emu
from forcemap.sim_devices.machine_emu import ADC, Counter, Machine, Pin, VirtualClock

# the vane's 8 reed-switch resistors at 0, 45, ..., 315 deg; in-between positions close two switches
VANE_BASE_OHMS = (33_000.0, 8_200.0, 1_000.0, 2_200.0, 3_900.0, 16_000.0, 120_000.0, 64_900.0)
N_CHANNELS = 5


def vane_resistance(direction_deg: float) -> float:
    """The vane's resistance with its 0 deg mark ``direction_deg`` from the wind (16 positions)."""
    pos = round((direction_deg % 360.0) / 22.5) % 16
    if pos % 2 == 0:
        return VANE_BASE_OHMS[pos // 2]
    a = VANE_BASE_OHMS[pos // 2]
    b = VANE_BASE_OHMS[(pos // 2 + 1) % 8]
    return a * b / (a + b)


def vane_voltage(
    direction_deg_relative_to_bow: float,
    vref: float = 3.3,
    pullup: float = 10_000.0,
    mounting_offset: float = 0.0,
) -> float:
    """Divider voltage for wind FROM ``direction_deg_relative_to_bow`` (clockwise from the bow).

    ``mounting_offset`` is where the vane's 0 deg mark points, clockwise from the bow (as in
    ``forcemap.host.decode.vane.decode_vane``).
    """
    r = vane_resistance(direction_deg_relative_to_bow - mounting_offset)
    return vref * r / (r + pullup)


RateSpec = float | Callable[[float], float] | Sequence[tuple[int, float]]


def pulse_times(
    rate: RateSpec, t0_us: int, t1_us: int, phase: float = 0.0
) -> tuple[list[int], float]:
    """Edge times in [t0_us, t1_us) of a pulse train, and the phase at ``t1_us``.

    ``rate`` is Hz: a constant, a function of time in us, or piecewise ``[(t_start_us, hz), ...]``
    (each rate holds from its start to the next). ``phase`` is the fraction of a period already
    done at ``t0_us`` (1.0: an edge is due right at ``t0_us``); pass the returned phase to the next call to continue the train seamlessly.
    A function rate is re-evaluated at each edge (and every 10 ms while it is 0).
    """
    out: list[int] = []
    if isinstance(rate, int | float):
        segments = [(t0_us, float(rate))]
    elif callable(rate):
        return _pulse_times_fn(rate, t0_us, t1_us, phase)
    else:
        segments = sorted((int(t), float(hz)) for t, hz in rate)
        earlier = [s for s in segments if s[0] <= t0_us]
        segments = ([(t0_us, earlier[-1][1])] if earlier else [(t0_us, 0.0)]) + [
            s for s in segments if t0_us < s[0] < t1_us
        ]
    for k, (start, hz) in enumerate(segments):
        end = segments[k + 1][0] if k + 1 < len(segments) else t1_us
        if hz <= 0:
            continue
        period = 1e6 / hz
        t = start + (1.0 - phase) * period
        # an edge belongs to this call if its integer time is before the end
        while round(t) < end:
            out.append(int(round(t)))
            t += period
        phase = min(1.0, 1.0 - (t - end) / period)
    return out, min(phase, 1.0)


def _pulse_times_fn(fn, t0_us, t1_us, phase):
    out = []
    t = float(t0_us)
    while t < t1_us:
        hz = fn(t)
        if hz <= 0:
            t += 10_000.0
            continue
        dt = (1.0 - phase) * 1e6 / hz
        if round(t + dt) >= t1_us:
            phase += (t1_us - t) * 1e-6 * hz
            break
        t += dt
        out.append(int(round(t)))
        phase = 0.0
    return out, min(phase, 1.0)


def add_bounce(
    times: Iterable[int], bounce_us: int = 300, n: int = 2, rng: random.Random | None = None
) -> list[int]:
    """``times`` with ``n`` bounce edges after each, within ``bounce_us`` (random if ``rng``)."""
    out = []
    for t in times:
        out.append(t)
        if rng is None:
            out.extend(t + bounce_us * (k + 1) // n for k in range(n))
        else:
            out.extend(sorted(t + rng.randint(1, bounce_us) for _ in range(n)))
    out.sort()
    return out


class _Out:
    __slots__ = ("write",)

    def __init__(self, write):
        self.write = write


class EmulatedBridge:
    """The bridge firmware on emulated pins. ``write(bytes) -> int|None`` takes each frame (None =
    USB write timeout); ``writable() -> bool`` (optional) False means the host is not reading and
    the CDC FIFO is full, so the firmware drops the frame.

    ``start_us``: the timeline at the first boot. ``ticks_start``: ``ticks_us()`` at each boot
    (0 by default, as on the boards; set near 2**30 to cross a wrap early). ``wheel_ppm``: four
    wheel pulses-per-metre values for HELLO. ``seed`` drives the boot ids and ADC noise.
    """

    def __init__(
        self,
        write,
        *,
        board: str = "nano_rp2040",
        seed: int = 0,
        start_us: int = 0,
        ticks_start: int | None = None,
        wheel_ppm=None,
        anemo_hz_per_mps: float = 1.5,
        writable=None,
    ):
        if board not in config.BOARDS:
            raise ValueError(f"unknown board {board!r}; one of {sorted(config.BOARDS)}")
        self.board = board
        self._out = _Out(write)
        self._writable = writable
        self._rng = random.Random(seed)
        self._ticks_start = 0 if ticks_start is None else ticks_start
        self._wheel_ppm = tuple(wheel_ppm) if wheel_ppm is not None else config.WHEEL_PULSES_PER_M
        self._anemo_hz_per_mps = anemo_hz_per_mps
        self.clock = VirtualClock(start_us, self._ticks_start)
        self.adc = ADC(vref=3.3, noise_v=0.002, seed=self._rng.getrandbits(32))
        self.adc.set_voltage(vane_voltage(0.0))
        self._pending: list[tuple[int, int]] = []
        self._pos = 0
        self._sorted = True
        self.boots = 0
        self.edges_fired = 0
        self._boot(machine_emu.PWRON_RESET)

    def _boot(self, cause: int) -> None:
        clock = self.clock
        self.machine = Machine(clock, cause)
        b = config.BOARDS[self.board]
        self.pins = [Pin(name, Pin.IN, Pin.PULL_UP) for name in b["pulse_pins"]]
        counters = []
        for i, pin in enumerate(self.pins):
            if i in b["hw_counter"]:
                hw = Counter(b["hw_counter"].index(i), src=pin, edge=Counter.FALLING)
                counters.append(CounterPulses(pin, clock, hw))
            else:
                counters.append(PulseCounter(pin, clock, config.LOCKOUT_US, hard=b["hard_irq"]))
        self.counters = counters
        self.wdt = self.machine.WDT(timeout=config.WDT_TIMEOUT_MS)
        self.firmware = Bridge(
            counters,
            Vane(self.adc, config.VANE_SAMPLES),
            self._out,
            clock,
            boot_id=self._rng.getrandbits(32),
            reset_cause=self.machine.reset_cause(),
            writable=self._writable,
            wdt=self.wdt,
            mem_free=lambda: 150_000,
            board=self.board,
            anemo_hz_per_mps=self._anemo_hz_per_mps,
            wheel_ppm=self._wheel_ppm,
        )
        self.boots += 1
        self.firmware.start()
        self._next_poll = clock.now

    @property
    def now_us(self) -> int:
        """The emulator's timeline in microseconds."""
        return self.clock.now

    @property
    def boot_us(self) -> int:
        """Timeline time of the current boot: a frame's timeline time is ``boot_us + frame.t_us``."""
        return self.clock.boot

    @property
    def boot_id(self) -> int:
        return self.firmware.boot_id

    def add_edges(self, channel: int, times_us: Iterable[int]) -> None:
        """Queue falling edges on ``channel`` (0 anemometer, 1-4 wheels) at timeline ``times_us``."""
        if not 0 <= channel < N_CHANNELS:
            raise ValueError(f"channel {channel} not in 0..{N_CHANNELS - 1}")
        now = self.clock.now
        if self._pos:
            del self._pending[: self._pos]
            self._pos = 0
        pend = self._pending
        last = pend[-1][0] if pend else now
        for t in times_us:
            t = int(t)
            if t < now:
                raise ValueError(f"edge at {t} us is before the current time {now} us")
            if t < last:
                self._sorted = False
            last = t
            pend.append((t, channel))

    def set_vane_voltage(self, volts: float) -> None:
        self.adc.set_voltage(volts)

    def advance_to(self, t_us: int) -> None:
        """Run the firmware until timeline ``t_us``: edges in time order, polls when due."""
        clock = self.clock
        if t_us < clock.now:
            raise ValueError(f"cannot go back from {clock.now} to {t_us} us")
        if not self._sorted:
            rest = self._pending[self._pos :]
            rest.sort(key=lambda e: e[0])
            self._pending = rest
            self._pos = 0
            self._sorted = True
        pend = self._pending
        i = self._pos
        n = len(pend)
        pins = self.pins
        fired = 0
        while True:
            stop = self._next_poll if self._next_poll <= t_us else t_us
            while i < n:
                te, ch = pend[i]
                if te > stop:
                    break
                clock.now = te
                pins[ch].fire()
                i += 1
                fired += 1
            if self._next_poll > t_us:
                break
            clock.now = self._next_poll
            wait = self.firmware.poll()
            self._next_poll = clock.now + (wait if wait > 0 else 1)
            if self.wdt.expired():
                self._pos = i
                self.reset(machine_emu.WDT_RESET)
                pins = self.pins
        clock.now = t_us
        self._pos = i
        self.edges_fired += fired

    def reset(self, cause: int = machine_emu.PWRON_RESET) -> None:
        """Board reset at the current time: new boot id, counts zero, ticks restart, HELLO."""
        self.clock.restart(self._ticks_start)
        self._boot(cause)
