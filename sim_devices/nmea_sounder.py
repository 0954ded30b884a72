"""The depth sounder: NMEA 0183 DPT, DBT and MTW with talker SD, paced at 4800 baud."""

from __future__ import annotations

import math
import random

import pynmea2
from forcemap.host.fuse.attitude import reading_over_slope

BAUD_BYTES_PER_S = 480.0  # 4800 baud, 8N1: ten bits a byte
LOST_RANGE = (3.0, 70.0)  # m: the returns of a sounder that has lost the bottom

# junk seen in real captures (NeutronDance.log: an Arduino multiplexer's status lines and boot text)
GARBAGE_LINES = (
    "!!VER:1.9,UID:MEGA,APX:0,APS:C,AAX:0,AAR:14.00,WSX:0,WSK:99,",
    "Initializing..",
    "SPI started",
    "Start nmea Rx - serial2 at 4800",
)


def sentence(talker: str, kind: str, fields: tuple[str, ...]) -> str:
    """One NMEA sentence with its checksum, built by pynmea2, without the line ending."""
    return pynmea2.TalkerSentence.sentence_types[kind](talker, kind, fields).render()


def address_checksum(line: str) -> str:
    """``line`` with its checksum computed over the address only (``$IIHDG,063,,,,*4B``)."""
    star = line.rfind("*")
    x = 0
    for b in line[1 : line.index(",")].encode("ascii"):
        x ^= b
    return f"{line[:star]}*{x:02X}"


class Sounder:
    """A single-beam sounder: depth below the transducer (DPT with offset, DBT) and water temperature."""

    def __init__(
        self,
        seed: int = 0,
        offset_m: float = 0.2,
        noise_m: float = 0.03,
        max_range: float = 100.0,
        false_echo_rate: float = 0.0,
        bottom_lost: tuple[float, float] | None = None,
        beam_deg: float | None = None,
        rough_range: float | None = None,
    ) -> None:
        self.rng = random.Random(seed)
        self.offset = offset_m
        self.noise = noise_m
        self.max_range = max_range
        self.false_echo_rate = false_echo_rate
        self.false_echoes = 0
        # (start, end) s of the run: in a rough sea the sounder loses the bottom, and its returns
        # scatter from LOST_RANGE[0] to LOST_RANGE[1] m from one ping to the next
        self.bottom_lost = bottom_lost
        self.lost_soundings = 0
        # the beam's full angle: the first return is the bed's nearest point in the cone (None: the
        # vertical, as a sounder on a level hull over a gentle bed reads)
        self.beam_deg = beam_deg
        # beyond this depth below the transducer, in a rough sea, the bottom is lost (None: never)
        self.rough_range = rough_range
        self.lost_times: list[float] = []  # s since the run's start, of every sounding lost

    def _false_echo(self, depth: float) -> bool:
        """In deep water a weak bottom return loses to a school of fish or the thermocline:
        ``false_echo_rate`` from 70 m, a share of it from 40 m."""
        p = self.false_echo_rate * min(max((depth - 40.0) / 30.0, 0.0), 1.0)
        return p > 0 and self.rng.random() < p

    def sentences(
        self,
        depth: float,
        temp: float,
        t: float = 0.0,
        tilt: tuple[float, float, float] = (0, 0, 0),
    ) -> list[str]:
        """DPT, DBT and MTW for the true depth below the surface and the water temperature
        (``t``: seconds since the run's start, for the bottom lost; ``tilt``: the transducer's tilt
        from the vertical, the bed's slope, both deg, and the lean's direction from down-slope)."""
        below = depth - self.offset
        if self.beam_deg is not None:
            below = reading_over_slope(below, tilt[0], tilt[1], self.beam_deg, tilt[2])
        d = max(below + self.rng.gauss(0.0, self.noise), 0.1)
        lost = self.bottom_lost
        beyond = self.rough_range is not None and depth - self.offset > self.rough_range
        if lost is not None and lost[0] <= t < lost[1]:
            self.lost_soundings += 1
            self.lost_times.append(t)
            d = self.rng.uniform(*LOST_RANGE)
        elif beyond:
            self.lost_soundings += 1
            self.lost_times.append(t)
            d = self.rng.uniform(LOST_RANGE[0], float(self.rough_range))
        elif self._false_echo(depth):
            self.false_echoes += 1
            d = self.rng.uniform(3.0, 20.0)
        return [
            sentence("SD", "DPT", (f"{d:.2f}", f"{self.offset:.2f}", f"{self.max_range:.1f}")),
            sentence(
                "SD", "DBT", (f"{d / 0.3048:.1f}", "f", f"{d:.2f}", "M", f"{d / 1.8288:.2f}", "F")
            ),
            sentence("SD", "MTW", (f"{temp + self.rng.gauss(0.0, 0.05):.1f}", "C")),
        ]


def make_sounder(
    seed: int, table: dict, faults: list, duration: float, heel: dict | None
) -> Sounder:
    """The scenario's sounder (its ``[sounder]`` table) with the run's faults (false echoes, the
    bottom lost, a range in a rough sea) and the `heel` effect's beam."""
    echoes = [f.rate for f in faults if f.kind == "false_echoes"]
    rough = [f.params.get("range", 90.0) for f in faults if f.kind == "beyond_range"]
    lost = [(f.start(duration), f.end(duration)) for f in faults if f.kind == "bottom_lost"]
    return Sounder(
        seed,
        float(table.get("offset_m", 0.2)),
        float(table.get("noise_m", 0.03)),
        false_echo_rate=float(table.get("false_echo_rate", max(echoes, default=0.0))),
        bottom_lost=lost[0] if lost else None,
        beam_deg=float(heel["beam_deg"]) if heel else None,
        rough_range=min(rough) if rough else None,
    )


def heel_roll(heel: dict | None, app_speed: float, app_angle: float) -> float:
    """The hull's roll (deg, starboard down positive) under the `heel` effect's parameters: to
    leeward, ``-max_deg min(1, (app_speed / wind_ref)^2) sin(app_angle)``; 0 without it."""
    if heel is None:
        return 0.0
    strength = min(1.0, (app_speed / float(heel["wind_ref"])) ** 2)
    return -float(heel["max_deg"]) * strength * math.sin(math.radians(app_angle))


def transducer_tilt(
    world, x: float, y: float, heading_deg: float, roll: float
) -> tuple[float, float, float]:
    """The transducer's tilt (deg), the bed's slope under it (deg) and the lean's direction from the
    down-slope direction (deg): a hull heeled to starboard points its transducer to port."""
    h = 1.0
    gx = (world.depth(x + h, y) - world.depth(x - h, y)) / (2 * h)
    gy = (world.depth(x, y + h) - world.depth(x, y - h)) / (2 * h)
    slope = math.degrees(math.atan(math.hypot(gx, gy)))
    down = math.degrees(math.atan2(gx, gy))  # toward deeper water, compass
    lean = heading_deg - 90.0 if roll >= 0 else heading_deg + 90.0
    return (abs(roll), slope, lean - down)


class Garbler:
    """NMEA damage like the real captures: spliced fragments, bad checksum digits, junk lines."""

    def __init__(self, rng: random.Random, rate: float) -> None:
        self.rng = rng
        self.rate = rate
        self.events = 0

    def apply(self, lines: list[str]) -> list[str]:
        out = []
        for i, s in enumerate(lines):
            r = self.rng.random()
            if r >= self.rate:
                out.append(s)
                continue
            self.events += 1
            kind = self.rng.randrange(4)
            if kind == 0:
                # a middle section lost: "$S" + the tail of this or the next sentence ($S1.62,F*39)
                other = lines[(i + 1) % len(lines)]
                cut = self.rng.randrange(2, 8)
                out.append(s[:cut] + other[self.rng.randrange(cut, len(other) - 4) :])
            elif kind == 1:
                # a sentence cut short runs into the next one ($SDDPT,2.56GPRMC...)
                out.append(s[: self.rng.randrange(8, len(s) - 3)] + lines[(i + 1) % len(lines)][1:])
            elif kind == 2:
                # one checksum digit garbled ($SDDPT,2.53,0.00,100.0*5V)
                out.append(s[:-1] + self.rng.choice(",.VW3"))
            else:
                out.append(self.rng.choice(GARBAGE_LINES))
                out.append(s)
        return out


class Uart:
    """Paces bytes at a serial line's rate: each chunk leaves when the one before it has gone."""

    def __init__(self, bytes_per_s: float, chunk: int = 16) -> None:
        self.ns_per_byte = 1e9 / bytes_per_s
        self.free_ns = 0
        self.chunk = chunk

    def send(self, t_ns: int, data: bytes) -> list[tuple[int, bytes]]:
        """(time the chunk's last byte leaves, chunk) pieces of ``data`` queued at ``t_ns``."""
        t = max(t_ns, self.free_ns)
        out = []
        for i in range(0, len(data), self.chunk):
            piece = data[i : i + self.chunk]
            t += int(len(piece) * self.ns_per_byte)
            out.append((t, piece))
        self.free_ns = t
        return out
