"""Synthetic raw byte streams of a survey with known truth: bridge 4 Hz, NMEA 1 Hz, MAVLink at Rover rates.

The boat circles and zig-zags through a uniform current under a uniform wind; every instrument is
encoded exactly as on the wire (COBS frames, NMEA with checksums, MAVLink 2 from pymavlink), each
with its own clock, and chunks arrive at the host with a few milliseconds of latency.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

from forcemap.host.decode.vane import DEFAULT_TABLE, ideal_raw
from forcemap.host.fuse.compensation import (
    apparent_from_true,
    boat_to_world,
    wheel_readings,
    world_to_boat,
)
from forcemap.protocol import wire
from pymavlink.dialects.v20 import ardupilotmega as mavlink

T0 = 1_750_000_000.0  # UNIX start of the synthetic survey
LAT0, LON0 = 33.99, -81.05
M_PER_DEG = 111_320.0


@dataclass
class Truth:
    """The scenario: constant wind (velocity of the air) and current (velocity of the water)."""

    wind: tuple[float, float] = (5.0, 1.0)  # east, north m/s: from ~259 deg
    current: tuple[float, float] = (0.4, -0.3)  # flows to ~127 deg
    speed: float = 1.5  # through the water, m/s
    turn_period_s: float = 120.0
    leeway_deg: float = 10.0
    anemo_mps_per_hz: float = 0.6667
    wheel_ppm: float = 10.8
    wheel_angles: tuple[float, ...] = (45.0, 135.0, -135.0, -45.0)
    bridge_drift: float = 40e-6
    bridge_offset_s: float = -1234.5
    mav_boot_offset_s: float = -300.0  # autopilot booted 300 s before T0
    extra: dict = field(default_factory=dict)

    def heading(self, t: float) -> float:
        return (90.0 + 60.0 * math.sin(2 * math.pi * t / self.turn_period_s)) % 360.0

    def yaw_rate(self, t: float) -> float:
        return (
            60.0 * 2 * math.pi / self.turn_period_s * math.cos(2 * math.pi * t / self.turn_period_s)
        )

    def leeway(self, t: float) -> float:
        return self.leeway_deg * math.sin(2 * math.pi * t / 37.0)

    def flow_boat(self, t: float) -> tuple[float, float]:
        """Water velocity relative to the hull, boat frame: the boat goes through the water at
        ``speed`` along heading + leeway."""
        lw = math.radians(self.leeway(t))
        return -self.speed * math.cos(lw), -self.speed * math.sin(lw)

    def boat_velocity(self, t: float) -> tuple[float, float]:
        f, s = self.flow_boat(t)
        fe, fn = boat_to_world(-f, -s, self.heading(t))
        return fe + self.current[0], fn + self.current[1]

    def apparent(self, t: float) -> tuple[float, float]:
        ve, vn = self.boat_velocity(t)
        return apparent_from_true(self.wind[0], self.wind[1], self.heading(t), ve, vn)


def _nmea(body: str) -> bytes:
    c = 0
    for ch in body.encode():
        c ^= ch
    return f"${body}*{c:02X}\r\n".encode()


def _vane_raw(angle_deg: float) -> int:
    sector = round((angle_deg % 360.0) / 22.5) % 16
    return ideal_raw(DEFAULT_TABLE[sector][1])


class _Mav:
    def __init__(self) -> None:
        self.buf: list[bytes] = []
        self.m = mavlink.MAVLink(self, srcSystem=1, srcComponent=1)

    def write(self, b: bytes) -> None:
        self.buf.append(bytes(b))

    def take(self) -> bytes:
        out = b"".join(self.buf)
        self.buf.clear()
        return out


def generate(duration_s: float, truth: Truth | None = None, seed: int = 1, dt: float = 0.01):
    """Events (source, t_mono_ns, t_wall_ns, bytes), sorted by arrival, and the Truth."""
    tr = truth or Truth()
    rng = random.Random(seed)
    events: list[tuple[str, int, int, bytes]] = []
    mono0 = 5_000_000_000
    last_arrival: dict[str, float] = {}

    def arrive(
        source: str, t: float, data: bytes, lat_ms: tuple[float, float] = (1.0, 15.0)
    ) -> None:
        ta = max(
            t + rng.uniform(*lat_ms) * 1e-3, last_arrival.get(source, 0.0)
        )  # a serial line keeps order
        last_arrival[source] = ta
        events.append((source, mono0 + int((ta - T0) * 1e9), int(ta * 1e9), data))

    boot_id = 0x1234ABCD
    seq = 0

    def dev_us(t: float) -> int:
        return int(((t - T0) * (1 + tr.bridge_drift) - tr.bridge_offset_s) * 1e6)

    hello = wire.pack_hello(
        (1, 0, 0), 1, 250_000, 30, 1 / tr.anemo_mps_per_hz, [tr.wheel_ppm] * 4, "synth", "A0"
    )
    arrive("bridge", T0, wire.encode(wire.HELLO, boot_id, seq, dev_us(T0), hello))
    seq += 1
    counts = [0.0] * 5
    last_edge = [0] * 5
    period = [0] * 5
    mav = _Mav()
    x = y = 0.0
    n = int(duration_s / dt)
    for k in range(1, n + 1):
        t_rel = k * dt
        t = T0 + t_rel
        ve, vn = tr.boat_velocity(t_rel)
        x += ve * dt
        y += vn * dt
        aws, awa = tr.apparent(t_rel)
        f, s = tr.flow_boat(t_rel)
        rates = [aws / tr.anemo_mps_per_hz] + [
            w * tr.wheel_ppm for w in wheel_readings(f, s, tr.wheel_angles)
        ]
        for i, r in enumerate(rates):
            before = int(counts[i])
            counts[i] += r * dt
            if int(counts[i]) > before and r > 0:
                frac = counts[i] - int(counts[i])
                last_edge[i] = dev_us(t - frac / r)
                period[i] = int(1e6 / r)
        if k % 25 == 0:  # 4 Hz
            chans = [(int(counts[i]) % wire.COUNT_MOD, last_edge[i], period[i]) for i in range(5)]
            payload = wire.pack_sample(_vane_raw(awa), chans)
            arrive("bridge", t, wire.encode(wire.SAMPLE, boot_id, seq, dev_us(t), payload))
            seq += 1
        if k % 1000 == 0:
            arrive(
                "bridge",
                t,
                wire.encode(
                    wire.STATUS,
                    boot_id,
                    seq,
                    dev_us(t),
                    wire.pack_status([seq, 0, 0, 100000, 0, 0]),
                ),
            )
            seq += 1
        boot_ms = int((t - T0 - tr.mav_boot_offset_s) * 1000)
        lat = LAT0 + y / M_PER_DEG
        lon = LON0 + x / (M_PER_DEG * math.cos(math.radians(LAT0)))
        hdg = tr.heading(t_rel)
        if k % 10 == 0:  # 10 Hz
            yaw = math.radians(hdg if hdg <= 180 else hdg - 360)
            mav.m.attitude_send(boot_ms, 0.0, 0.0, yaw, 0.0, 0.0, math.radians(tr.yaw_rate(t_rel)))
        if k % 20 == 0:  # 5 Hz
            mav.m.global_position_int_send(
                boot_ms,
                int(lat * 1e7),
                int(lon * 1e7),
                0,
                0,
                int(round(vn * 100)),
                int(round(ve * 100)),
                0,
                int(hdg * 100),
            )
            sog = math.hypot(ve, vn)
            cog = math.degrees(math.atan2(ve, vn)) % 360
            mav.m.gps_raw_int_send(
                int((t - T0 - tr.mav_boot_offset_s) * 1e6),
                3,
                int(lat * 1e7),
                int(lon * 1e7),
                0,
                80,
                120,
                int(sog * 100),
                int(cog * 100),
                12,
            )
        if k % 25 == 0:  # 4 Hz
            mav.m.vfr_hud_send(0.0, math.hypot(ve, vn), int(hdg), 40, 0.0, 0.0)
        if k % 100 == 0:  # 1 Hz
            mav.m.heartbeat_send(10, 3, 0, 0, 4)
            mav.m.system_time_send(int(t * 1e6), boot_ms)
            depth = 3.0 + 2.0 * math.sin(x / 50.0)
            nm = _nmea(f"SDDPT,{depth:.2f},0.3,") + _nmea(
                f"SDDBT,{depth / 0.3048:.1f},f,{depth:.2f},M,{depth / 1.8288:.1f},F"
            )
            nm += _nmea("SDMTW,18.5,C")
            arrive("depth", t, nm, (20.0, 60.0))
        data = mav.take()
        if data:
            arrive("mavlink", t, data)
    events.sort(key=lambda e: e[1])
    return events, tr


def truth_wind_current(tr: Truth, t_rel: float) -> dict[str, float]:
    """True values at a time, for checks: wind and current over ground and the relative flow."""
    f, s = tr.flow_boat(t_rel)
    return {
        "wind_east": tr.wind[0],
        "wind_north": tr.wind[1],
        "current_east": tr.current[0],
        "current_north": tr.current[1],
        "flow_fwd": f,
        "flow_stbd": s,
        "heading": tr.heading(t_rel),
    }


__all__ = ["T0", "Truth", "generate", "truth_wind_current", "world_to_boat"]
