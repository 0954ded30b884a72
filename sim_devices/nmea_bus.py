"""An NMEA-only boat's instrument bus (38400 baud): GNSS, compass, speed log, and the faults of issue 20.

Always on the bus when it is enabled: a GNSS (``GPRMC`` and ``GPGGA``, ``hhmmss.ss``, 5-decimal
minutes, 1 Hz, a slowly wandering position error), a fluxgate compass (``HCHDG``, magnetic with its
variation, 5 Hz, 1 deg noise) and a speed log (``VWVHW``, 1 Hz). The source faults add:

- ``second_gnss``: a second receiver on the same ``GP`` talker, its antenna 2 m to starboard,
  whole seconds and 3-decimal minutes every 2 s, its sentences 1 s late;
- ``relay_position``: the instrument bus re-sends the first GNSS's fix as ``IIRMC`` at 3 decimals;
- ``second_compass``: the instrument bus's damped true heading, ``IIHDT`` at 1 Hz (2 s time constant);
- ``rate_of_turn``: a rate gyro's ``TIROT`` at 2 Hz;
- ``poor_gnss``: the ``GP`` receiver is autonomous (GGA quality 1, HDOP 2.1), its error 2 m,
  wandering in seconds (10 s time constant);
- ``nav_receivers`` (issue 29): the ``GP`` receiver becomes a coarse one (4-decimal minutes, a 1 m
  error wandering in 10 s, 1 Hz) and a precise ``GN`` receiver (5 decimals, a 0.1 m error, every
  4 s) joins it; each sends RMC, GGA and GLL, each sentence at its own instant and UTC stamp
  (0, 0.3 and 0.6 s after its epoch);
- ``late_compass`` (issue 29): a gyro compass ``HEHDT`` (2 Hz, 0.5 deg noise) whose headings are
  5 s late joins the on-time ``HCHDG`` fluxgate; HDT ranks first by the default quality order, so
  a pipeline that picks one source picks the late one;
- ``dgps_gnss``: a second receiver, ``GNRMC`` and ``GNGGA`` at 4-decimal minutes, 1 Hz, DGPS (GGA
  quality 2, RMC mode D, HDOP 0.9), its error 0.3 m; for ``lost`` = (start s, duration s) it loses
  its corrections: autonomous, HDOP 4.5, a 3 m error wandering in seconds.

The faults of issue 28 (real logs that break the rules):

- ``no_variation``: the compass's HDG has empty variation fields (and RMC has none): the bus's
  variation is the engine's, IGRF-14's at the scenario's origin and start, so that the truth is known;
- ``checksum_variant``: every sentence's checksum is computed over its address only (``*4B`` on
  every ``HCHDG``...), as the Irene logs of 2013 do;
- ``position_jump``: for ``jump`` = (start s, duration s) the GNSS's fixes are JUMP_KM north of the
  boat (a stale fix replayed at the start of a log); ``jumped`` counts the fix sentences sent so;
- ``speed_log`` (STW / gain, axis turned ``misalign`` deg), ``dead_log`` (0.00 kn), ``rot_deg_s``.

Every device's readings are the boat's true motion at the moment they describe (the truth table).
"""

from __future__ import annotations

import math
import random
import time
from collections import deque
from dataclasses import dataclass

from forcemap.host.fuse.declination import igrf_declination
from forcemap.host.vessel.geodesy import LocalFrame

from .nmea_sounder import address_checksum, sentence

BUS_BYTES_PER_S = 3840.0  # 38400 baud, NMEA 0183-HS
KNOT = 1852.0 / 3600.0
FAULTS = (
    "second_gnss",
    "relay_position",
    "second_compass",
    "rate_of_turn",
    "poor_gnss",
    "dgps_gnss",
    "no_variation",
    "checksum_variant",
    "position_jump",
    "speed_log",
    "dead_log",
    "rot_deg_s",
    "nav_receivers",
    "late_compass",
)
JUMP_KM = 500.0


# nav_receivers: each receiver sends RMC, GGA and GLL, each at its own instant and UTC stamp
# (seconds after the receiver's epoch); issue 29
SENTENCE_OFFSETS_S = {"RMC": 0.0, "GGA": 0.3, "GLL": 0.6}
LATE_COMPASS_S = 5.0


@dataclass
class Motion:
    """The boat at one instant: local metres, heading (deg), yaw rate (deg/s), velocities (m/s)."""

    t: float  # UNIX seconds
    x: float
    y: float
    heading: float
    yaw_rate: float
    ve: float
    vn: float
    stw: float


def _hhmmss(t: float, decimals: int) -> str:
    tm = time.gmtime(math.floor(t))
    base = f"{tm.tm_hour:02d}{tm.tm_min:02d}{tm.tm_sec:02d}"
    if decimals == 0:
        return base
    frac = t - math.floor(t)
    return base + f"{frac:.{decimals}f}"[1:]


def _ddmmyy(t: float) -> str:
    tm = time.gmtime(math.floor(t))
    return f"{tm.tm_mday:02d}{tm.tm_mon:02d}{tm.tm_year % 100:02d}"


def _angle(value: float, deg_digits: int, decimals: int, hemis: str) -> tuple[str, str]:
    a = abs(value)
    d = int(a)
    m = round((a - d) * 60.0, decimals)
    if m >= 60.0:
        d, m = d + 1, 0.0
    return f"{d:0{deg_digits}d}{m:0{3 + decimals}.{decimals}f}", hemis[0] if value >= 0 else hemis[
        1
    ]


@dataclass
class Fix:
    """What a receiver's fix is: GGA quality, RMC mode, HDOP, and its error (m, time constant s)."""

    quality: int = 1
    mode: str = "A"
    hdop: float = 0.9
    err_m: float = 0.5
    tau_s: float = 60.0


POOR = Fix(1, "A", 2.1, 2.0, 10.0)
DGPS = Fix(2, "D", 0.9, 0.3, 60.0)
LOST = Fix(1, "A", 4.5, 3.0, 10.0)  # DGPS without its corrections


class Gnss:
    """One receiver: its own fingerprint (time decimals, minute decimals), rate, lag and antenna."""

    def __init__(
        self,
        geo: LocalFrame,
        rng: random.Random,
        *,
        talker: str = "GP",
        period_s: float = 1.0,
        time_decimals: int = 2,
        minute_decimals: int = 5,
        late_s: float = 0.0,
        antenna_m: tuple[float, float] = (0.0, 0.0),  # (forward, starboard)
        gga: bool = True,
    ) -> None:
        self.geo, self.rng = geo, rng
        self.talker, self.period = talker, period_s
        self.td, self.md = time_decimals, minute_decimals
        self.late, self.antenna, self.gga = late_s, antenna_m, gga
        self.next_t: float | None = None
        self.err = [0.0, 0.0]  # a wandering error (m): its size and time constant are the fix's
        self.set_fix(Fix())

    def set_fix(self, q: Fix) -> None:
        self.q = q

    def fix(self, m: Motion) -> tuple[float, float, float, float]:
        """(lat, lon, sog kn, cog deg) of the antenna at ``m``."""
        a = 1.0 - math.exp(-self.period / self.q.tau_s)
        for i in (0, 1):
            self.err[i] += a * (
                self.rng.gauss(0.0, self.q.err_m) * math.sqrt(2.0 / a) - self.err[i]
            )
        h = math.radians(m.heading)
        f, s = self.antenna
        x = m.x + f * math.sin(h) + s * math.cos(h) + self.err[0]
        y = m.y + f * math.cos(h) - s * math.sin(h) + self.err[1]
        lat, lon = self.geo.to_latlon(x, y)
        ve, vn = m.ve + self.rng.gauss(0.0, 0.03), m.vn + self.rng.gauss(0.0, 0.03)
        return (
            float(lat),
            float(lon),
            math.hypot(ve, vn) / KNOT,
            math.degrees(math.atan2(ve, vn)) % 360,
        )

    def sentences(
        self, m: Motion, fix: tuple[float, float, float, float], kinds: tuple[str, ...] = ()
    ) -> list[str]:
        """RMC (and GGA) of ``fix`` stamped ``m.t``; ``kinds``: only these (RMC, GGA, GLL)."""
        lat, lon, sog, cog = fix
        q = self.q
        la, ns = _angle(lat, 2, self.md, "NS")
        lo, ew = _angle(lon, 3, self.md, "EW")
        hms = _hhmmss(m.t, self.td)
        out = [
            sentence(
                self.talker,
                "RMC",
                (
                    hms,
                    "A",
                    la,
                    ns,
                    lo,
                    ew,
                    f"{sog:.1f}",
                    f"{cog:.1f}",
                    _ddmmyy(m.t),
                    "",
                    "",
                    q.mode,
                ),
            )
        ]
        if self.gga and (not kinds or "GGA" in kinds):
            gga = (hms, la, ns, lo, ew, str(q.quality), "09", f"{q.hdop:.1f}", "12.0", "M")
            gga += ("0.0", "M", "", "")
            out.append(sentence(self.talker, "GGA", gga))
        if kinds:
            out = [x for x in out if x[3:6] in kinds]
            if "GLL" in kinds:
                out.append(sentence(self.talker, "GLL", (la, ns, lo, ew, hms, "A", q.mode)))
        return out


class NmeaBus:
    """Sentences due at each step; ``step`` gets the boat's true motion, returns (delay s, text)."""

    def __init__(
        self,
        geo: LocalFrame,
        seed: int,
        variation_deg: float,
        faults: set[str],
        lost: tuple[float, float] | None = None,
        jump: tuple[float, float] | None = None,
    ) -> None:
        # one random stream per device: a fault added leaves the other devices' noise as it was
        self.rng = {k: random.Random(seed * 10 + i) for i, k in enumerate(("hdg", "rot", "vhw"))}
        self.variation = variation_deg
        self.faults = set(faults)
        self.history: deque[Motion] = deque(maxlen=200)
        self.gnss = Gnss(geo, random.Random(seed * 10 + 3))
        self.gnss2 = Gnss(
            geo,
            random.Random(seed * 10 + 4),
            period_s=2.0,
            time_decimals=0,
            minute_decimals=3,
            late_s=1.0,
            antenna_m=(0.0, 2.0),
            gga=False,
        )
        if "poor_gnss" in self.faults:
            self.gnss.set_fix(POOR)
        self.gnss3 = Gnss(geo, random.Random(seed * 10 + 5), talker="GN", minute_decimals=4)
        self.gnss3.set_fix(DGPS)
        self.lost = lost  # (start, duration) s from the first step: the DGPS corrections lost
        self.jump = jump  # (start, duration) s from the first step: the GNSS's fixes jump away
        self.jumped = 0
        self.t_first: float | None = None
        self.relay_md = 3
        self.next = dict.fromkeys(("gnss", "gnss2", "gnss3", "hdg", "hdt", "rot", "vhw"), 0.0)
        self.period = {
            "gnss": 1.0,
            "gnss2": 2.0,
            "gnss3": 1.0,
            "hdg": 0.2,
            "hdt": 1.0,
            "rot": 0.5,
            "vhw": 1.0,
        }
        if "nav_receivers" in self.faults:
            self.gnss.md, self.gnss.q = 4, Fix(1, "A", 1.5, 1.0, 10.0)
            self.gnss4 = Gnss(geo, random.Random(seed * 10 + 6), talker="GN", period_s=4.0)
            self.gnss4.q = Fix(2, "D", 0.8, 0.1, 60.0)
            for kind, off in SENTENCE_OFFSETS_S.items():
                self.next[f"gnss {kind}"] = self.next[f"gnss4 {kind}"] = off
                self.period[f"gnss {kind}"] = self.gnss.period
                self.period[f"gnss4 {kind}"] = self.gnss4.period
        self.receivers_started = False
        self.next.setdefault("gyro", 0.0)
        self.period["gyro"] = 0.5
        self.damped: float | None = None
        self.t_prev: float | None = None
        self.last_fix: tuple[Motion, tuple[float, float, float, float]] | None = None
        self.gain, self.misalign = 1.0, 0.0  # the speed log's fault (calibration_faults)
        self.dead: tuple[float, float] | None = None

    def calibration_faults(self, faults: list) -> None:
        """The speed log's gain and misalignment and its dead stretch (s from the first step)."""
        for f in faults:
            if f.kind == "speed_log":
                self.gain = f.params.get("gain", 1.06)
                self.misalign = f.params.get("misalign", 2.0)
            elif f.kind == "dead_log":
                self.dead = (f.start(0.0), f.dur)

    def _due(self, key: str, t: float) -> bool:
        if t + 1e-9 < self.next[key]:
            return False
        self.next[key] = max(self.next[key] + self.period[key], t)
        return True

    def _receivers(self, m: Motion) -> list[str]:
        """nav_receivers: each sentence of each receiver when due, at its own instant and stamp."""
        out: list[str] = []
        if not self.receivers_started:
            self.receivers_started = True
            for key in ("gnss", "gnss4"):
                for kind, off in SENTENCE_OFFSETS_S.items():
                    self.next[f"{key} {kind}"] = m.t + off
        for key, gnss in (("gnss", self.gnss), ("gnss4", self.gnss4)):
            for kind in SENTENCE_OFFSETS_S:
                if self._due(f"{key} {kind}", m.t):
                    out += gnss.sentences(m, gnss.fix(m), (kind,))
        return out

    def _damp(self, m: Motion) -> None:
        if self.damped is None or self.t_prev is None:
            self.damped = m.heading
        else:
            a = 1.0 - math.exp(-(m.t - self.t_prev) / 2.0)
            d = (m.heading - self.damped + 180.0) % 360.0 - 180.0
            self.damped = (self.damped + a * d) % 360.0
        self.t_prev = m.t

    def step(self, m: Motion) -> list[str]:
        """Every sentence the bus sends at ``m.t`` (the second GNSS's describe 1 s earlier)."""
        self.history.append(m)
        self._damp(m)
        out: list[str] = []
        t = m.t
        self.t_first = t if self.t_first is None else self.t_first
        if "nav_receivers" in self.faults:
            out += self._receivers(m)
        elif self._due("gnss", t):
            fix = self.gnss.fix(m)
            if self._jumping(t):
                fix = (fix[0] + JUMP_KM / 111.195, *fix[1:])
                self.jumped += 2 if self.gnss.gga else 1
            out += self.gnss.sentences(m, fix)
            self.last_fix = (m, fix)
            if "relay_position" in self.faults:
                lat, lon, sog, cog = fix
                la, ns = _angle(lat, 2, self.relay_md, "NS")
                lo, ew = _angle(lon, 3, self.relay_md, "EW")
                f = (_hhmmss(t, 0), "A", la, ns, lo, ew, f"{sog:.1f}", f"{cog:.1f}", _ddmmyy(t))
                out.append(sentence("II", "RMC", f + ("", "", "A")))
        if "dgps_gnss" in self.faults and self._due("gnss3", t):
            s = t - self.t_first
            lost = self.lost is not None and self.lost[0] <= s < self.lost[0] + self.lost[1]
            self.gnss3.set_fix(LOST if lost else DGPS)
            out += self.gnss3.sentences(m, self.gnss3.fix(m))
        if "second_gnss" in self.faults and self._due("gnss2", t):
            past = next((h for h in reversed(self.history) if h.t <= t - self.gnss2.late), None)
            if past is not None:
                out += self.gnss2.sentences(past, self.gnss2.fix(past))
        if "late_compass" in self.faults and self._due("gyro", t):
            late = next((h for h in self.history if h.t >= t - LATE_COMPASS_S), m)
            hdt = (late.heading + self.rng["rot"].gauss(0.0, 0.5)) % 360.0
            out.append(sentence("HE", "HDT", (f"{hdt:.1f}", "T")))
        if self._due("hdg", t):
            hdg = m.heading - self.misalign
            mag = (hdg - self.variation + self.rng["hdg"].gauss(0.0, 1.0)) % 360.0
            var = f"{abs(self.variation):.1f}", "E" if self.variation >= 0 else "W"
            if "no_variation" in self.faults:
                var = ("", "")
            out.append(sentence("HC", "HDG", (f"{mag:.1f}", "", "", *var)))
        if "second_compass" in self.faults and self._due("hdt", t):
            out.append(sentence("II", "HDT", (f"{self.damped:.1f}", "T")))
        gyro = self.faults & {"rate_of_turn", "rot_deg_s"}
        if gyro and self._due("rot", t):
            per_s = "rot_deg_s" in self.faults
            rot = m.yaw_rate * (1.0 if per_s else 60.0) + self.rng["rot"].gauss(0.0, 3.0)
            out.append(sentence("TI", "ROT", (f"{rot:.2f}" if per_s else f"{rot:.1f}", "A")))
        if self._due("vhw", t):
            stw = max(m.stw + self.rng["vhw"].gauss(0.0, 0.02), 0.0) / KNOT / self.gain
            dead = self.dead
            if dead is not None and dead[0] <= t - self.t_first < dead[0] + dead[1]:
                stw = 0.0
            out.append(sentence("VW", "VHW", ("", "T", "", "M", f"{stw:.2f}", "N", "", "K")))
        if "checksum_variant" in self.faults:
            out = [address_checksum(x) for x in out]
        return out

    def _jumping(self, t: float) -> bool:
        if self.jump is None or self.t_first is None:
            return False
        s = t - self.t_first
        return self.jump[0] <= s < self.jump[0] + self.jump[1]


def make_bus(geo: LocalFrame, seed: int, scenario, faults: list) -> NmeaBus:
    """The bus for a simulation's scenario and faults, with the faults' windows (and, without
    variation in its sentences, the Earth's field as IGRF-14 has it: the truth an import must find)."""
    kinds = {f.kind for f in faults if f.kind in FAULTS}
    var = scenario.magnetic_variation_deg
    if "no_variation" in kinds:
        var = igrf_declination(scenario.lat0, scenario.lon0, scenario.t0)
    windows = {}
    for kind in ("dgps_gnss", "position_jump"):
        f = next((f for f in faults if f.kind == kind), None)
        if f is not None and f.dur > 0:
            windows[kind] = (f.start(0.0), f.dur)
    return NmeaBus(geo, seed, var, kinds, windows.get("dgps_gnss"), windows.get("position_jump"))
