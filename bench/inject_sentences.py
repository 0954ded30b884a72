"""The sentence-by-sentence core of ``bench/inject_nmea.py`` (whose docstring says what changes and
why): the log's clock, the rewriting of each sentence type, and the lines of a whole capture."""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

from forcemap.host.errors import CliError
from forcemap.host.vessel.geodesy import (
    LocalFrame,
    to_direction,
    velocity,
    world_to_boat,
    wrap_to_180,
)

from bench.inject_effects import Effect
from bench.nmea_fields_like import (
    Unreadable,
    angle_like,
    checksum_convention,
    checksum_for,
    date_of,
    latlon_like,
    num,
    number_like,
    read_latlon,
    split_sentence,
    tod_of,
)

KN = 1852.0 / 3600.0
KMH = 1000.0 / 3600.0
MPH = 1609.344 / 3600.0
FOOT = 0.3048
FATHOM = 1.8288
DAY = 86400.0
MAX_STAMP_JUMP_S = 3600.0
SPEED_UNITS = {"N": KN, "M": 1.0, "K": KMH, "S": MPH}
TIMED = ("RMC", "GGA", "GLL", "GNS", "ZDA")
POSITION = {"RMC": (2, 3, 4, 5), "GGA": (1, 2, 3, 4), "GLL": (0, 1, 2, 3), "GNS": (1, 2, 3, 4)}
TIME_FIELD = {"RMC": 0, "GGA": 0, "GLL": 4, "GNS": 0, "ZDA": 0}
DEPTHS = ("DBT", "DBS", "DBK")


class Skip(Exception):
    """A sentence left as recorded, with the reason it is counted under."""


@dataclass
class Report:
    """What an injection did: lines, sentences changed by type, lines left untouched by reason."""

    lines: int = 0
    changed: Counter = field(default_factory=Counter)
    untouched: Counter = field(default_factory=Counter)
    t0: float = math.nan
    t1: float = math.nan
    declination: float | None = None

    def summary(self) -> list[str]:
        out = [f"{self.lines} lines, {sum(self.changed.values())} sentences rewritten"]
        out += [f"  {k}: {n}" for k, n in sorted(self.changed.items())]
        if self.untouched:
            out.append(f"{sum(self.untouched.values())} left as recorded:")
            out += [f"  {k}: {n}" for k, n in sorted(self.untouched.items())]
        if self.declination is not None:
            out.append(
                f"heading: IGRF-14 declination {self.declination:+.1f} deg (none in the log)"
            )
        return out


# --- the log's clock ---------------------------------------------------------------------------


class Clock:
    """Each sentence's UNIX time: its own stamp, else the last timed sentence's (module doc)."""

    def __init__(self, date0: float) -> None:
        self.date0 = date0
        self.day = 0.0
        self.prev_tod: float | None = None
        self.now: float | None = None

    def stamp(self, stype: str, f: list[str], trusted: bool = True) -> float | None:
        """The time of this sentence (None before the first timed sentence). Only a ``trusted``
        sentence (its checksum matches a convention) sets the clock, as only those are the
        importer's anchors."""
        if not trusted or stype not in TIMED or len(f) <= TIME_FIELD[stype]:
            return self.now
        tod = tod_of(f[TIME_FIELD[stype]])
        if tod is None:
            return self.now
        day = self.day
        if self.prev_tod is not None and tod < self.prev_tod - DAY / 2:
            day += DAY
        t = self.date0 + day + tod
        if self.now is not None and abs(t - self.now) > MAX_STAMP_JUMP_S:
            return self.now
        self.day, self.prev_tod, self.now = day, tod, t
        return t


def _sentences(lines: list[bytes]):  # type: ignore[no-untyped-def]
    """(index, prefix, body, checksum, its convention, tail, type, fields) of each line that holds
    a sentence (not a proprietary one)."""
    for i, line in enumerate(lines):
        parts = split_sentence(line)
        if parts is None or parts[1].startswith("P"):
            continue
        prefix, body, cs, tail = parts
        f = body.split(",")
        stype = f[0][-3:]
        convention = None if cs is None else checksum_convention(body, cs)
        yield i, prefix, body, cs, convention, tail, stype, f[1:]


def log_date(lines: list[bytes]) -> float | None:
    """The UTC midnight the log starts on, by the importer's rule (issue 60): the day most dated
    sentences of a valid fix give (RMC of status A, a ZDA whose talker's last position had a fix),
    midnights crossed counted; a date without a fix never counts; a ZDA with no position of its
    talker counts only where no valid fix is dated."""
    votes: dict[bool | None, Counter] = {True: Counter(), None: Counter()}
    has_fix: dict[str, bool] = {}
    days, prev = 0.0, None
    for _, _, body, _, convention, _, stype, f in _sentences(lines):
        if not convention or stype not in TIMED or len(f) <= max(TIME_FIELD[stype], 5):
            continue
        talker = body.split(",", 1)[0][:-3]
        if stype in ("RMC", "GLL"):
            has_fix[talker] = f[1 if stype == "RMC" else 5].upper() == "A"
        elif stype in ("GGA", "GNS"):
            has_fix[talker] = f[5] not in ("", "0") and not set(f[5].upper()) <= {"N"}
        tod = tod_of(f[TIME_FIELD[stype]])
        if tod is None:
            continue
        if prev is not None and tod < prev - DAY / 2:
            days += DAY
        prev = tod
        if (d := date_of(stype, f)) is None:
            continue
        ok = has_fix[talker] if stype == "RMC" else has_fix.get(talker)
        if ok is not False:
            votes[ok][d - days] += 1
    for v in votes.values():
        if v:
            return v.most_common(1)[0][0]
    return None


def survey(lines: list[bytes]) -> tuple[float, float, float, tuple[float, float] | None]:
    """(date0, first time, last time, first fix) of a capture, as the importer finds its date."""
    date0 = log_date(lines)
    clock = Clock(date0 or 0.0)
    t0 = t1 = None
    fix = None
    for *_, convention, _tail, stype, f in _sentences(lines):
        t = clock.stamp(stype, f, convention is not None)
        if t is not None:
            t0 = t if t0 is None else t0
            t1 = t if t1 is None else max(t1, t)
        if fix is None and stype in POSITION:
            a, b, c, d = POSITION[stype]
            try:
                lat, lon = read_latlon(f[a], f[b]), read_latlon(f[c], f[d])
            except (Unreadable, IndexError):
                continue
            if lat is not None and lon is not None and convention is not None:
                fix = (lat, lon)
    if t0 is None:
        raise CliError("no time in this log (no RMC, GGA, GLL, GNS or ZDA with a UTC stamp)")
    return date0 or 0.0, t0, t1, fix


# --- the rewriting -----------------------------------------------------------------------------


class Injector:
    """Rewrites one sentence at a time (fields after the address), keeping the log's state: its
    clock, its last true heading, its variation."""

    def __init__(
        self,
        effect: Effect,
        t0: float,
        date0: float,
        fix: tuple[float, float] | None,
        true_wind: str = "water",
    ) -> None:
        self.effect, self.t0, self.true_wind = effect, t0, true_wind
        self.clock = Clock(date0)
        self.frame = LocalFrame(*fix) if fix else None
        self.fix = fix
        self.heading: float | None = None
        self.variation: float | None = None
        # each rewritten field's rounding error, carried into the same field's next value (error
        # diffusion): a change smaller than the log's resolution (a wind angle in whole degrees, a
        # sounding in decimetres) is not lost to rounding, nor a slow effect made a staircase
        self.carry: dict[tuple[str, int], float] = {}
        self.igrf: float | None = None

    # the effect at a time
    def current(self, t: float) -> tuple[float, float]:
        c = self.effect.current
        if c is None:
            return 0.0, 0.0
        e, n = c.velocity(t - self.t0)
        return float(e), float(n)

    def offset(self, t: float) -> tuple[float, float]:
        c = self.effect.current
        if c is None:
            return 0.0, 0.0
        e, n = c.offset(t - self.t0)
        return float(e), float(n)

    def level(self, t: float) -> float:
        lv = self.effect.level
        return 0.0 if lv is None else float(lv.value(t - self.t0))

    # the heading the apparent wind is turned with
    def _declination(self) -> float:
        if self.variation is not None:
            return self.variation
        if self.igrf is None:
            from forcemap.host.fuse.declination import igrf_declination

            if self.fix is None:
                raise Skip("no position for the declination")
            self.igrf = igrf_declination(self.fix[0], self.fix[1], self.t0)
        return self.igrf

    def note_heading(self, stype: str, f: list[str]) -> None:
        if stype == "RMC" and len(f) > 10 and f[9] and f[10]:
            self.variation = float(f[9]) * (-1.0 if f[10].upper() == "W" else 1.0)
        if stype == "HDG" and len(f) >= 5:
            if f[3] and f[4]:
                self.variation = float(f[3]) * (-1.0 if f[4].upper() == "W" else 1.0)
            if f[0]:
                dev = float(f[1]) * (-1.0 if f[2].upper() == "W" else 1.0) if f[1] else 0.0
                self.heading = float(f[0]) + dev + self._declination()
        elif stype == "HDM" and f and f[0]:
            self.heading = float(f[0]) + self._declination()
        elif stype == "HDT" and f and f[0]:
            self.heading = float(f[0])

    def rewrite(self, stype: str, f: list[str], t: float) -> list[str] | None:
        """The new fields, or None for a sentence this injection does not touch."""
        g = list(f)
        ce, cn = self.current(t)
        if stype in POSITION and self.effect.current is not None:
            self._move(stype, g, t)
            if stype == "RMC":
                self._ground_velocity(stype, g, (6, 7, None), [(6, KN)], ce, cn)
            return g
        if stype == "VTG" and self.effect.current is not None:
            if len(g) < 8 or g[1].upper() != "T":
                raise Skip("VTG without its T/M/N/K letters")
            self._ground_velocity(stype, g, (4, 0, 2), [(4, KN), (6, KMH)], ce, cn)
            return g
        if stype == "VDR" and self.effect.current is not None:
            self._ground_velocity(stype, g, (4, 0, 2), [(4, KN)], ce, cn)
            return g
        if self.effect.current is not None and stype in ("MWV", "VWR", "VWT", "MWD"):
            water = stype == "VWT" or (stype == "MWV" and g[1].upper() == "T") or stype == "MWD"
            if water and self.true_wind == "ground":
                return None
            return self._wind(stype, g, -ce, -cn)
        if self.effect.level is not None and stype in DEPTHS + ("DPT",):
            return self._deeper(stype, g, self.level(t))
        return None

    # every rewritten field through these: its rounding error is carried into its next value
    def _number(self, tag: str, g: list[str], i: int, value: float) -> None:
        v = value + self.carry.get((tag, i), 0.0)
        g[i] = number_like(g[i], v)
        self.carry[(tag, i)] = v - float(g[i])

    def _angle(self, tag: str, g: list[str], i: int, value: float) -> float:
        """Writes a compass angle; returns the angle written."""
        v = value + self.carry.get((tag, i), 0.0)
        g[i] = angle_like(g[i], v)
        self.carry[(tag, i)] = wrap_to_180(v - float(g[i]))
        return float(g[i])

    def _speeds(
        self, tag: str, g: list[str], known: list[tuple[int, float]], change: float
    ) -> None:
        """Each speed field (index, m/s per unit) changed by ``change`` m/s: every unit keeps its
        own rounding of the recorded value, so a change of nothing leaves every field as it was."""
        for i, u in known:
            self._number(tag, g, i, num(g[i]) + change / u)

    def _move(self, stype: str, g: list[str], t: float) -> None:
        a, b, c, d = POSITION[stype]
        lat, lon = read_latlon(g[a], g[b]), read_latlon(g[c], g[d])
        if lat is None or lon is None:
            return
        de, dn = self.offset(t)
        x, y = self.frame.to_local(lat, lon)
        nlat, nlon = self.frame.to_latlon(x + de, y + dn)
        for (i, h, axis), v in zip(((a, b, "lat"), (c, d, "lon")), (nlat, nlon), strict=True):
            v = float(v) + self.carry.get((stype, i), 0.0)
            g[i], g[h] = latlon_like(g[i], g[h], v, axis)
            self.carry[(stype, i)] = v - read_latlon(g[i], g[h])

    def _ground_velocity(  # type: ignore[no-untyped-def]
        self, stype, g, at, speeds, ce, cn
    ) -> None:
        """Speed fields ``speeds`` [(index, m/s per unit)] and the courses at ``at`` (speed, true
        course, magnetic course or None) become the recorded velocity plus (ce, cn)."""
        _, course_i, mag_i = at
        known = [(i, u) for i, u in speeds if num(g[i]) is not None]
        if not known:
            return
        sog = num(g[known[0][0]]) * known[0][1]
        cog = num(g[course_i])
        if cog is None and sog > 0:
            raise Skip("a speed over ground without its course")
        ve, vn = velocity(sog, cog or 0.0)
        ne, nn = ve + ce, vn + cn
        speed = math.hypot(ne, nn)
        self._speeds(stype, g, known, speed - sog)
        if cog is not None and speed > 1e-9:
            course = to_direction(ne, nn)
            self._angle(stype, g, course_i, course)
            if mag_i is not None and num(g[mag_i]) is not None:
                self._angle(stype, g, mag_i, num(g[mag_i]) + course - cog)

    def _wind(self, stype: str, g: list[str], de: float, dn: float) -> list[str]:
        """Air velocity relative to the boat (or the water) plus the world vector (de, dn)."""
        if stype == "MWD":
            return self._wind_world(g, de, dn)
        if self.heading is None:
            raise Skip(f"{stype} before any heading")
        if stype == "MWV":
            spd = [(2, SPEED_UNITS.get(g[3].upper()))] if len(g) > 3 else []
            angle = num(g[0])
        else:  # VWR, VWT: 0-180 to port (L) or starboard (R), knots, m/s, km/h
            spd = [(i, u) for i, u in ((2, KN), (4, 1.0), (6, KMH)) if len(g) > i]
            a = num(g[0])
            angle = None if a is None else (-a if g[1].upper() == "L" else a)
        known = [(i, u) for i, u in spd if u is not None and num(g[i]) is not None]
        if angle is None or not known:
            raise Skip(f"{stype} without its angle or speed")
        tag = stype + (g[1].upper() if stype == "MWV" else "")  # R and T alternate in one MWV
        s = num(g[known[0][0]]) * known[0][1]
        r = math.radians(angle)
        fwd, stbd = -s * math.cos(r), -s * math.sin(r)
        cf, cs = world_to_boat(de, dn, self.heading)
        fwd, stbd = fwd + cf, stbd + cs
        speed = math.hypot(fwd, stbd)
        new_angle = math.degrees(math.atan2(-stbd, -fwd))
        self._speeds(tag, g, known, speed - s)
        if speed < 1e-9:  # no wind at all: no direction to write, the recorded one stays
            return g
        if stype == "MWV":
            self._angle(tag, g, 0, new_angle)
            return g
        v = new_angle + self.carry.get((tag, 0), 0.0)  # signed: the carry keeps its side
        g[0] = angle_like(g[0], abs(v))
        self.carry[(tag, 0)] = v - math.copysign(float(g[0]), v)
        if 0.0 < float(g[0]) < 180.0:  # dead ahead or astern keeps the recorded side
            side = "L" if v < 0 else "R"
            g[1] = side.lower() if g[1].islower() else side
        return g

    def _wind_world(self, g: list[str], de: float, dn: float) -> list[str]:
        """MWD: direction FROM (true, magnetic) and speed (knots, m/s) in the world frame."""
        known = [(i, u) for i, u in ((4, KN), (6, 1.0)) if len(g) > i and num(g[i]) is not None]
        d = num(g[0])
        if d is None or not known:
            raise Skip("MWD without its true direction or speed")
        s = num(g[known[0][0]]) * known[0][1]
        we, wn = velocity(s, d + 180.0)
        ne, nn = we + de, wn + dn
        speed = math.hypot(ne, nn)
        new_from = math.degrees(math.atan2(-ne, -nn))
        self._speeds("MWD", g, known, speed - s)
        if speed < 1e-9:
            return g
        self._angle("MWD", g, 0, new_from)
        if num(g[2]) is not None:
            self._angle("MWD", g, 2, num(g[2]) + new_from - d)
        return g

    def _deeper(self, stype: str, g: list[str], level: float) -> list[str]:
        units = [(0, 1.0)] if stype == "DPT" else [(0, FOOT), (2, 1.0), (4, FATHOM)]
        for i, u in units:
            if len(g) > i and (v := num(g[i])) is not None:
                self._number(stype, g, i, v + level / u)
        return g


def inject_lines(
    lines: list[bytes], effect: Effect, true_wind: str = "water"
) -> tuple[list[bytes], Effect, Report]:
    """The lines with the effect injected (each line's ending kept), the truth's time span and
    the Report. ``lines`` are split on LF with their CR kept, so joining with LF gives the file."""
    date0, t0, t1, fix = survey(lines)
    eff = effect.resolved(t1 - t0)
    if eff.current is not None and fix is None:
        raise CliError("no position in this log: a current has nothing to move")
    inj = Injector(eff, t0, date0, fix, true_wind)
    rep = Report(lines=len(lines), t0=t0, t1=t1)
    out = list(lines)
    for i, prefix, body, cs, convention, tail, stype, f in _sentences(lines):
        t = inj.clock.stamp(stype, f, convention is not None)
        t = t0 if t is None else t
        try:
            inj.note_heading(stype, f)
            new = inj.rewrite(stype, f, t)
        except Skip as e:
            rep.untouched[str(e)] += 1
            continue
        except (Unreadable, IndexError, ValueError):
            rep.untouched[f"{stype} with a field that is not what it should be"] += 1
            continue
        if new is None or new == f:
            continue
        if cs is not None and convention is None:
            rep.untouched[f"{stype} whose checksum matches no convention (damaged)"] += 1
            continue
        nbody = ",".join([body.split(",", 1)[0], *new])
        text = "$" + nbody + ("" if cs is None else "*" + checksum_for(nbody, convention, cs))
        out[i] = prefix + text.encode("latin-1") + tail
        rep.changed[stype] += 1
    rep.declination = None if inj.variation is not None else inj.igrf
    return out, eff, rep
