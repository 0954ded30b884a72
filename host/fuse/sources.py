"""One source per quantity: who gave each reading, and which of them the samples use.

A source is the connection, the talker and the sentence (``nmea GPRMC``) or the message
(``mavlink GLOBAL_POSITION_INT``); position sentences add a fingerprint (their time field's format
and the decimals of their minutes, ``[hhmmss.ss 5dp]``), which tells apart two receivers that share
a talker. Every reading goes to ``/source/reading``; only the chosen source's readings reach the
boat state and the assembler, so two receivers or two compasses are never interleaved.

The choice follows the boat file's ``[sources]`` priorities (substrings of a source's name, first
preferred), then, for position, the receivers' fix quality (fix class, then a clearly worse HDOP:
forcemap.host.fuse.fix_quality), then the default order (``default_rank``). A source that has been
silent for longer than ``timeout`` (or three of its own intervals, if longer) gives way to the next
one; it is taken back as soon as it speaks again. A receiver whose fix becomes better than the one
in use takes over only once it has been the better for DWELL_S at each of its readings, so that a
fix that hesitates between two classes does not make the position jump back and forth.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, field
from functools import cmp_to_key
from typing import Any

from forcemap.host.fuse import fix_quality as fq

QUANTITIES = (
    "position",
    "heading",
    "yaw_rate",
    "stw",
    "depth",
    "wind",
    "wind_true",
    "water_temp",
    "velocity",  # VTG, for a position source without its own (GGA, GLL)
    "attitude",  # the hull's roll and pitch (deg)
)
DEFAULT_TIMEOUT_S = 5.0
DWELL_S = 10.0  # a better fix takes over once it has been the better for this long
KEEP_EVERY_S = 0.2  # readings kept for the disagreement analysis: at most one per 0.2 s
KEEP_MAX = 40_000  # per source: over two hours at 5 Hz
# talkers that re-send what another instrument measured: after the instrument itself
RELAY_TALKERS = ("II", "IN", "AI", "EC", "EI", "CD")
AUTOPILOT_CONNECTIONS = ("mavlink", "dataflash")
SENTENCE_ORDER = {
    "position": ("GLOBAL_POSITION_INT", "GPS_RAW_INT", "RMC", "GNS", "GGA", "GLL"),
    "heading": ("HDT", "ATTITUDE", "HDG", "HDM", "VHW"),
    "yaw_rate": ("ROT", "ATTITUDE", "derivative"),
    "depth": ("DPT", "WATER_DEPTH", "RANGEFINDER", "DISTANCE_SENSOR", "DBT", "DBS"),
    "attitude": ("ATTITUDE", "XDR"),
}
WHY = {
    "priority": "listed first in the boat file's [sources]",
    "quality": "best by the default quality order",
    "fix": "the better fix",
    "only": "the only instrument",
    "fallback": "the preferred source was silent",
}


def receiver_name(connection: str, talker: str, fingerprint: str) -> str:
    """The group of one receiver's position sentences: ``nmea GP* [hhmmss.ss 5dp]``."""
    return f"{connection} {talker}* [{fingerprint}]"


def nmea_fingerprint(text: str, stype: str) -> str:
    """``hhmmss.ss 5dp``: the time field's format and the decimals of the latitude's minutes."""
    star = text.rfind("*")
    fields = text[1 : star if star > 0 else len(text)].split(",")
    where = {"RMC": (1, 3), "GGA": (1, 2), "GNS": (1, 2), "GLL": (5, 1)}.get(stype)
    if where is None:
        return ""
    ti, li = where
    tf = fields[ti] if ti < len(fields) else ""
    lf = fields[li] if li < len(fields) else ""
    tfmt = "hhmmss" + ("." + "s" * len(tf.split(".", 1)[1]) if "." in tf else "")
    dp = len(lf.split(".", 1)[1]) if "." in lf else 0
    return f"{tfmt} {dp}dp"


def source_name(connection: str, talker: str, kind: str, fingerprint: str = "") -> str:
    """``nmea GPRMC [hhmmss.ss 5dp]``, ``mavlink ATTITUDE``."""
    name = f"{connection} {talker}{kind}"
    return f"{name} [{fingerprint}]" if fingerprint else name


def split_name(name: str) -> tuple[str, str, str]:
    """(connection, talker, sentence or message) of a source name."""
    parts = name.split(" ")
    ident = parts[1] if len(parts) > 1 else ""
    if parts[0] in AUTOPILOT_CONNECTIONS or len(ident) != 5:
        return parts[0], "", ident
    return parts[0], ident[:2], ident[2:]


def message_of(name: str) -> str:
    """The sentence or message of a source name (``RMC`` of ``nmea GPRMC [hhmmss.ss 5dp]``)."""
    return split_name(name)[2] if name else ""


def quality_key(name: str) -> str:
    """Whose fix quality a position source carries: an autopilot's connection (GPS_RAW_INT says
    how good the fix under GLOBAL_POSITION_INT is), else the receiver (its group) itself."""
    conn = name.split(" ", 1)[0]
    return conn if conn in AUTOPILOT_CONNECTIONS else name


def default_rank(quantity: str, name: str) -> tuple:
    """The default quality order (lower first): the autopilot first (it fuses everything), then
    instruments before relays, more decimals, and the order of ``SENTENCE_ORDER`` (true heading
    before magnetic, ROT before the autopilot's gyro before a heading's derivative)."""
    conn, talker, kind = split_name(name)
    autopilot = conn in AUTOPILOT_CONNECTIONS
    relay = talker in RELAY_TALKERS
    dp = 0
    if "dp]" in name:
        dp = int(name.rsplit(" ", 1)[1].rstrip("dp]") or 0)
    order = SENTENCE_ORDER.get(quantity, ())
    pos = order.index(kind) if kind in order else len(order)
    return (not autopilot, relay, -dp, pos)


@dataclass
class SourceTrack:
    """One source of one quantity: its readings (thinned), count, last time and interval."""

    name: str
    rank: tuple
    n: int = 0
    used: int = 0
    last_t: float = -math.inf
    interval: float = 0.0
    t: deque = field(default_factory=lambda: deque(maxlen=KEEP_MAX))
    v: deque = field(default_factory=lambda: deque(maxlen=KEEP_MAX))

    def observe(self, t: float, value: tuple) -> None:
        if self.n and 0 < t - self.last_t < 60:
            dt = t - self.last_t
            self.interval = dt if not self.interval else 0.9 * self.interval + 0.1 * dt
        self.n += 1
        self.last_t = max(self.last_t, t)
        if not self.t or t - self.t[-1] >= KEEP_EVERY_S:
            self.t.append(t)
            self.v.append(value)

    def silent(self, t: float, timeout: float) -> bool:
        return t - self.last_t > max(timeout, 3.0 * self.interval)


class SourceSelector:
    """Chooses one source per quantity; ``accept`` says whether a reading is the chosen one's."""

    def __init__(
        self,
        priorities: dict[str, list[str]] | None = None,
        timeouts: dict[str, float] | None = None,
    ) -> None:
        self.priorities = {q: [p.lower() for p in v] for q, v in (priorities or {}).items()}
        self.timeouts = timeouts or {}
        self.tracks: dict[str, dict[str, SourceTrack]] = {q: {} for q in QUANTITIES}
        self.groups: dict[str, dict[str, SourceTrack]] = {}
        self.chosen: dict[str, str] = {}  # quantity -> the chosen group
        self.member: dict[str, str] = {}  # quantity -> the source of its last reading used
        self.switches: Counter[str] = Counter()
        self.fixes: dict[str, fq.FixReports] = {}  # quality_key -> what it said of its fix
        self.group_of: dict[str, str] = {}  # position source -> its group
        self.pending: dict[tuple[str, str], float] = {}  # (quantity, better group) -> since

    def rank(self, quantity: str, name: str) -> tuple:
        low = name.lower()
        prio = self.priorities.get(quantity, [])
        listed = next((i for i, p in enumerate(prio) if p in low), len(prio))
        return (listed, *default_rank(quantity, name))

    def report_fix(
        self, key: str, kind: str, t: float, fix: int | None, hdop: float | None = None
    ) -> None:
        """What receiver ``key`` (a group, or an autopilot's source) says of its fix at ``t``."""
        reports = self.fixes.setdefault(quality_key(key), fq.FixReports())
        reports.report(kind, t, fix, hdop)

    def quality(self, key: str) -> fq.Quality:
        """(fix class, HDOP) of a position group or source (None where unknown)."""
        reports = self.fixes.get(quality_key(self.group_of.get(key, key)))
        return reports.current() if reports else (None, None)

    def compare(self, quantity: str, a: SourceTrack, b: SourceTrack) -> tuple[int, str]:
        """(sign, what decides): sign < 0 if group ``a`` is preferred to ``b``; what decides is
        ``priority`` (the boat file), ``fix`` (position: the fix quality), ``quality`` (the
        default order) or empty (a tie)."""
        if a.rank[0] != b.rank[0]:
            return a.rank[0] - b.rank[0], "priority"
        if quantity == "position":
            c = fq.compare(self.quality(a.name), self.quality(b.name))
            if c:
                return c, "fix"
        if a.rank != b.rank:
            return (-1 if a.rank < b.rank else 1), "quality"
        return 0, ""

    def _switch(
        self, quantity: str, key: str, t: float, ct: SourceTrack | None, first: bool
    ) -> None:
        """Make ``key`` the chosen group if the current one ``ct`` is silent or worse (a better
        fix must have held DWELL_S, unless ``key`` is seen for the first time: at the start of a
        log, the first receiver heard is not kept for its luck)."""
        if ct is not None:
            timeout = self.timeouts.get(quantity, DEFAULT_TIMEOUT_S)
            if not ct.silent(t, timeout):
                sign, what = self.compare(quantity, self.groups[quantity][key], ct)
                if sign >= 0:
                    self.pending.pop((quantity, key), None)
                    return
                if what == "fix" and not first:
                    since = self.pending.setdefault((quantity, key), t)
                    if t - since < DWELL_S:
                        return
            self.switches[quantity] += 1
        for k in [k for k in self.pending if k[0] == quantity]:
            del self.pending[k]
        self.chosen[quantity] = key

    def accept(
        self, quantity: str, name: str, t: float, value: tuple, group: str | None = None
    ) -> bool:
        """Record a reading of ``quantity`` from ``name`` at ``t``; True if it is the one to use.

        ``group``: the instrument ``name`` belongs to (one receiver's RMC, GGA and GLL carry the
        same fix); the choice is between groups, each ranked by its best sentence.
        """
        tracks = self.tracks[quantity]
        tr = tracks.get(name)
        if tr is None:
            tr = tracks[name] = SourceTrack(name, self.rank(quantity, name))
        tr.observe(t, value)
        key = group or name
        if quantity == "position":
            self.group_of[name] = key
        groups = self.groups.setdefault(quantity, {})
        g = groups.get(key)
        first = g is None
        if g is None:
            g = groups[key] = SourceTrack(key, tr.rank)
        g.rank = min(g.rank, tr.rank)
        g.last_t = max(g.last_t, t)
        g.interval = max(g.interval, tr.interval)
        cur = self.chosen.get(quantity)
        if cur != key:
            self._switch(quantity, key, t, groups.get(cur) if cur else None, first)
        ok = self.chosen.get(quantity) == key
        if ok:
            tr.used += 1
            self.member[quantity] = name
        return ok

    def reason(self, quantity: str) -> str:
        """Why the chosen source of ``quantity`` is the one in use (with, for position, the
        fix quality its receiver reported: ``the better fix: DGPS, HDOP 0.9 vs GPS, HDOP 2.1 ...``)."""
        groups = self.groups.get(quantity, {})
        g = groups.get(self.chosen.get(quantity, ""))
        if g is None:
            return ""
        own = fq.describe(self.quality(g.name)) if quantity == "position" else ""
        others = [o for o in groups.values() if o is not g]
        if not others:
            return WHY["only"] + (f"; fix {own}" if own else "")
        order = cmp_to_key(lambda a, b: self.compare(quantity, a, b)[0])
        best = min(others, key=order)
        sign, what = self.compare(quantity, g, best)
        if sign > 0:
            return WHY["fallback"]
        if what == "fix":
            return f"{WHY['fix']}: {own} vs {fq.describe(self.quality(best.name))} of {best.name}"
        why = WHY["priority"] if what == "priority" else WHY["quality"]
        return why + (f"; fix {own}" if own else "")

    def chosen_track(self, quantity: str) -> str:
        """The best-ranked source (sentence) of the chosen group: RMC of a receiver's RMC and GGA."""
        members = [tr for tr in self.tracks[quantity].values() if tr.used]
        key = self.chosen.get(quantity, "")
        stem, _, fp = key.partition("*")
        inside = [
            tr
            for tr in members
            if tr.name == key or (fp and tr.name.startswith(stem) and tr.name.endswith(fp))
        ]
        best = min(inside or members, key=lambda tr: (tr.rank, -tr.used), default=None)
        return best.name if best else ""

    def summary(self) -> dict[str, Any]:
        """Per quantity: the chosen source, why, switches, and every source's count and use."""
        out: dict[str, Any] = {}
        for q, tracks in self.tracks.items():
            if not tracks:
                continue
            out[q] = {
                "chosen": self.chosen_track(q),
                "group": self.chosen.get(q, ""),
                "why": self.reason(q),
                "switches": self.switches[q],
                "sources": {
                    n: {"readings": tr.n, "used": tr.used, "rank": list(tr.rank)}
                    for n, tr in tracks.items()
                },
            }
            if q == "position":
                out[q]["fix"] = {n: fq.describe(self.quality(n)) for n in tracks}
        return out
