"""What the bridge's sensors see: paddle wheels, anemometer and vane, from the boat's true motion."""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from typing import Any

from .bridge_emu import add_bounce, pulse_times, vane_voltage

# paper configuration: one wheel per quadrant, +-45 and +-135 deg off the bow
WHEEL_ANGLES_DEG = (45.0, 135.0, -135.0, -45.0)


@dataclass
class InstrumentConfig:
    """Sensor constants; a scenario's ``[instruments]`` table overrides any of them."""

    wheel_angles_deg: tuple[float, ...] = WHEEL_ANGLES_DEG
    wheel_pulses_per_m: tuple[float, ...] = (10.8, 10.8, 10.8, 10.8)
    wheel_positions_m: tuple[tuple[float, float], ...] = ((0.0, 0.0),) * 4  # (forward, starboard)
    wheel_stall: float = 0.06  # m/s below which a wheel does not turn
    wheel_s0: float = 0.12  # m/s; reading = s (1 - exp(-s / s0)): under-reads at low speed
    wheel_noise: float = 0.02  # fractional std of the pulse rate, correlated over wheel_noise_tau
    wheel_noise_tau: float = 2.0  # s
    anemo_hz_per_mps: float = 1.5  # 2.4 km/h per Hz
    anemo_start: float = 0.4  # m/s, cups do not turn below this
    anemo_bounce_us: int = 300
    anemo_bounces: int = 2
    vane_jitter_deg: float = 5.0  # the vane hunts about the true direction
    vane_offset_deg: float = 0.0  # where the vane's 0 mark points, clockwise from the bow

    @classmethod
    def from_table(cls, table: dict[str, Any]) -> InstrumentConfig:
        cfg = cls()
        for k, v in table.items():
            if not hasattr(cfg, k):
                raise ValueError(f"unknown [instruments] key {k!r}")
            cur = getattr(cfg, k)
            setattr(
                cfg,
                k,
                tuple(tuple(x) if isinstance(x, list) else x for x in v)
                if isinstance(cur, tuple)
                else type(cur)(v),
            )
        return cfg


def wheel_response(speed: float, stall: float, s0: float) -> float:
    """Speed a paddle wheel turns at for water moving ``speed`` (m/s) along its axis (unsigned)."""
    s = abs(speed)
    if s < stall:
        return 0.0
    return s * (1.0 - math.exp(-s / s0))


def along_axis(u: float, v: float, r: float, angle_deg: float, pos: tuple[float, float]) -> float:
    """Signed water speed along a wheel's axis, relative to the hull (water moves aft when u > 0)."""
    a = math.radians(angle_deg)
    pu = u - r * pos[1]
    pv = v + r * pos[0]
    return -(pu * math.cos(a) + pv * math.sin(a))


@dataclass
class Readings:
    """True values at the sensors (the truth) for one step."""

    wheels: list[float]  # unsigned along-axis water speed at each nominal axis
    app_speed: float
    app_angle: float  # deg FROM, relative to the bow, (-180, 180]


@dataclass
class Sensors:
    """Turns the boat's motion into pulse edges and a vane voltage for the emulated bridge."""

    cfg: InstrumentConfig
    seed: int = 0
    misalign: dict[int, float] = field(default_factory=dict)  # wheel index (0-3) -> extra deg
    upwash_k: float = 0.0
    _phase: list[float] = field(default_factory=lambda: [0.0] * 5)
    _noise: list[float] = field(default_factory=lambda: [0.0] * 4)

    def __post_init__(self) -> None:
        self.rng = random.Random(self.seed)

    def truth(self, u: float, v: float, r: float, rel_f: float, rel_s: float) -> Readings:
        """True wheel speeds and apparent wind; ``rel_f, rel_s`` is the air's velocity relative to the boat."""
        c = self.cfg
        wheels = [
            abs(along_axis(u, v, r, a, p))
            for a, p in zip(c.wheel_angles_deg, c.wheel_positions_m, strict=True)
        ]
        app = math.hypot(rel_f, rel_s)
        ang = math.degrees(math.atan2(-rel_s, -rel_f)) if app > 0 else 0.0
        if ang <= -180.0:
            ang += 360.0
        return Readings(wheels, app, ang)

    def rates(
        self, u: float, v: float, r: float, app_speed: float, sog: float, dt: float
    ) -> list[float]:
        """Pulse rates (Hz): anemometer, then wheels 1-4 as mounted (misalignment included)."""
        c = self.cfg
        a = 1.0 - math.exp(-dt / c.wheel_noise_tau)
        out = []
        meas = app_speed * (1.0 + self.upwash_k * math.hypot(u, v))
        out.append(c.anemo_hz_per_mps * meas if meas >= c.anemo_start else 0.0)
        for i in range(4):
            ang = c.wheel_angles_deg[i] + self.misalign.get(i, 0.0)
            s = along_axis(u, v, r, ang, c.wheel_positions_m[i])
            self._noise[i] += a * (
                self.rng.gauss(0.0, c.wheel_noise) * math.sqrt(2.0 / a) - self._noise[i]
            )
            out.append(
                c.wheel_pulses_per_m[i]
                * wheel_response(s, c.wheel_stall, c.wheel_s0)
                * (1.0 + self._noise[i])
            )
        return out

    def edges(self, rates: list[float], t0_us: int, t1_us: int) -> list[list[int]]:
        """Edge times on the bridge's timeline in [t0_us, t1_us) for each channel; reed bounce on the anemometer."""
        out = []
        self.primary = []  # the real pulses, before reed bounce: what the firmware should count
        for ch, hz in enumerate(rates):
            times, self._phase[ch] = pulse_times(hz, t0_us, t1_us, self._phase[ch])
            self.primary.append(times)
            if ch == 0 and times and self.cfg.anemo_bounces:
                times = add_bounce(
                    times, self.cfg.anemo_bounce_us, self.cfg.anemo_bounces, self.rng
                )
            out.append(times)
        return out

    def vane_volts(self, app_angle: float) -> float:
        """Divider voltage for the apparent wind angle, with the vane hunting about it."""
        jitter = self.rng.gauss(0.0, self.cfg.vane_jitter_deg)
        return vane_voltage(app_angle + jitter, mounting_offset=self.cfg.vane_offset_deg)
