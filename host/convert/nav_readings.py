"""Every navigation reading of a log, from its raw records: the smoother's input.

The pipeline logs every reading of every source on ``/source/reading``, used or not. Positions of
one receiver (its RMC, GGA and GLL: one group, named as forcemap.host.fuse.sources.receiver_name
does) are one source, each sentence at its own UTC time field (read from the ``/nmea/sentence``
logged just before the reading) where it carries one that agrees with the log time within
``MAX_UTC_SKEW_S``; a capture's line times are spread between stamps, a receiver's stamps are not.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.fuse import fix_quality as fq
from forcemap.host.fuse import nav_model
from forcemap.host.fuse.sources import receiver_name, split_name
from forcemap.host.log.mcap import read_messages

MAX_UTC_SKEW_S = nav_model.MAX_UTC_SKEW_S
MOVED_DEG = 1.5e-5  # about 1.5 m: one stamp on positions this far apart is not one fix
TIME_FIELD = nav_model.TIME_FIELD
QUANTITIES = ("position", "velocity", "heading", "yaw_rate", "stw")
TOPICS = ("/source/reading", "/nmea/sentence")
_WANTED = re.compile(
    rb'"quantity":"(?:%s)"|"type":"(?:RMC|GGA|GLL|GNS)"' % "|".join(QUANTITIES).encode()
)


def wanted(topic: str, data: bytes) -> bool:
    """Whether a message of TOPICS is one the smoother reads (decoding the others is spared)."""
    return topic not in TOPICS or _WANTED.search(data) is not None


@dataclass
class SourceData:
    """One source's readings of one quantity: times (s) and values (n, k), and whether used."""

    name: str
    t: list[float] = field(default_factory=list)
    v: list[list[float]] = field(default_factory=list)
    used: int = 0
    stamped: int = 0  # readings on their own UTC time field
    fixes: list[int] = field(default_factory=list)  # fix classes its sentences stated
    hdops: list[float] = field(default_factory=list)
    decimals: int = 0  # of a position's minutes
    log_t: list[float] = field(default_factory=list)  # the log times, where ``t`` is a UTC stamp
    coarse_stamps: bool = False  # its stamps are coarser than its fixes: the log times are used

    def check_stamps(self) -> None:
        """A receiver whose stamps repeat for different positions (a stamp every 10 s on fixes
        every 2 s) is not timed by them: its readings go back to their log times."""
        if not self.stamped or len(self.t) < 3:
            return
        v = np.array([x[:2] for x in self.v], dtype=float)
        if nav_model.coarse_stamps(self.t, v, MOVED_DEG):
            self.t, self.coarse_stamps, self.stamped = list(self.log_t), True, 0

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(self.t, float)
        width = max((len(x) for x in self.v), default=1)
        v = np.full((len(self.v), width), np.nan)
        for i, x in enumerate(self.v):
            v[i, : len(x)] = [np.nan if y is None else float(y) for y in x]
        order = np.argsort(t, kind="stable")
        return t[order], v[order]


_tod, _on_day = nav_model.time_of_day, nav_model.on_day


def _fix(text: str, stype: str) -> tuple[int | None, float | None, int]:
    """(fix class, HDOP, decimals of the latitude's minutes) a position sentence states."""
    star = text.rfind("*")
    f = text[1 : star if star > 0 else len(text)].split(",")

    def get(i: int) -> str:
        return f[i] if i < len(f) else ""

    lat = get(2 if stype in ("GGA", "GNS") else 3 if stype == "RMC" else 1)
    dp = len(lat.split(".", 1)[1]) if "." in lat else 0
    try:
        if stype == "GGA":
            hd = get(8)
            return fq.gga_fix(int(get(6) or 0)), (float(hd) if hd else None), dp
        mode = get(12) if stype == "RMC" else get(7) if stype == "GLL" else ""
        return (fq.MODE.get(mode[:1]) if mode else None), None, dp
    except ValueError:
        return None, None, dp


def group_of(name: str) -> str:
    """The receiver (group) of a position source: one receiver's RMC, GGA and GLL are one."""
    conn, talker, kind = split_name(name)
    if conn != "nmea" or kind not in TIME_FIELD:
        return name
    fp = name[name.find("[") + 1 : name.rfind("]")] if "[" in name else ""
    return receiver_name(conn, talker, fp)


def read(paths: Sequence[str | os.PathLike[str]]) -> dict[str, dict[str, SourceData]]:
    """Per quantity, per source (positions: per receiver), every reading of the logs."""
    messages = read_messages(paths, TOPICS, accept=wanted)
    return collect((m.topic, m.log_time_ns, m.message) for m in messages)


def collect(messages: Iterable[tuple[str, int, dict]]) -> dict[str, dict[str, SourceData]]:
    """``read`` of (topic, log time ns, message) in the order they were logged."""
    out: dict[str, dict[str, SourceData]] = {q: {} for q in QUANTITIES}
    last_tod: dict[str, float | None] = {}  # talker+type -> the time field of its last sentence
    last_fix: dict[str, tuple[int | None, float | None, int]] = {}
    for topic, log_ns, msg in messages:
        if topic == "/nmea/sentence":
            stype = msg.get("type", "")
            if stype in TIME_FIELD and msg.get("valid"):
                key = f"{msg.get('source')} {msg.get('talker')}{stype}"
                last_tod[key] = _tod(msg.get("text", ""), stype)
                last_fix[key] = _fix(msg.get("text", ""), stype)
            continue
        q = msg.get("quantity")
        if q not in out:
            continue
        name = str(msg.get("source", ""))
        t = log_ns * 1e-9
        key = name
        stamped = False
        fix = None
        if q == "position":
            key = group_of(name)
            conn, talker, kind = split_name(name)
            sk = f"{conn} {talker}{kind}"
            tod = last_tod.pop(sk, None) if kind in TIME_FIELD else None
            fix = last_fix.pop(sk, None)
            if tod is not None:
                utc = _on_day(t, tod)
                if utc is not None:
                    t, stamped = utc, True
        src = out[q].setdefault(key, SourceData(key))
        if fix is not None:
            if fix[0] is not None:
                src.fixes.append(fix[0])
            if fix[1] is not None:
                src.hdops.append(fix[1])
            src.decimals = max(src.decimals, fix[2])
        src.t.append(t)
        src.log_t.append(log_ns * 1e-9)
        src.v.append(list(msg.get("value") or []))
        src.used += bool(msg.get("used"))
        src.stamped += stamped
    for src in out["position"].values():
        src.check_stamps()
    return {q: s for q, s in out.items() if s}
