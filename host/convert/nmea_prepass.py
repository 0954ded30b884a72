"""What an NMEA import learns from the whole file before the pipeline reads it line by line.

Three things: a UTC time for every line on the log's day (forcemap.host.convert.importers' docstring
says how, and below how the day is found); where the boat's track is (the median of every fix and the
radius it spans), so that position jumps at the very start of a log are told from the track
(forcemap.host.fuse.position_jumps); and, when no time sentence was accepted, what rejected them, so
the error names the cause (a checksum variant, with the option that accepts it) rather than saying the
log has no time.

The log's day comes from its valid fixes (issue 60): each dated sentence (RMC, ZDA) says which UTC
midnight the log started on (its own date less the midnights the times of day have crossed since the
first time sentence). A date from a sentence that says it has no fix (RMC status V, a ZDA of a
receiver whose last position said no fix: a receiver dates its sentences from its own clock before its
first fix) never dates the log; among the valid fixes the day most of them give wins (a date one day
off within MIDNIGHT_S of midnight is a receiver rolling its date over late or early, not a
disagreement). A ZDA with no position of its talker to vouch for it dates the log only when no valid
fix does. The rows are all kept and put on the winning day, and what it overruled is counted in the
import's timing note and in a ``qa.time.date`` finding (``import`` and ``check`` show both).

The calibrated import reads a capture twice (forcemap.host.convert.self_calibration): inside ``kept()``
the second pass takes the first one's lines, times and track instead of reading them again (on the
7.4-hour San Francisco Bay log, about 4 s of the import's 51 s of CPU).
"""

from __future__ import annotations

import contextlib
import time
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from forcemap.host.convert.capture_file import capture_lines
from forcemap.host.decode import nmea_checksum
from forcemap.host.decode.nmea import NmeaParser, Sentence, parsed_once
from forcemap.host.fuse.position_jumps import track_seed
from forcemap.host.log.qa_records import QaFinding

TIME_TYPES = (b"RMC,", b"GGA,", b"GLL,", b"ZDA,")
POSITION_TYPES = (b"RMC,", b"GGA,", b"GLL,")
DAY = 86400.0
MIDNIGHT_S = 120.0  # a date a day off this close to midnight: the receiver rolled it over late
SURE_SHARE = 2 / 3  # the valid fixes' day is in doubt (red) when fewer of them agree
FIX, NO_FIX, UNCONFIRMED = "valid fix", "no fix", "unconfirmed"


@dataclass(frozen=True)
class Prepass:
    """A capture's lines, the notes reading it gave, each line's UNIX time and how it was found, and
    the track's seed (None without UTC or without a fix)."""

    lines: list[bytes]
    notes: list[str]
    times: list[float]
    how: str
    seed: tuple[float, float, float] | None
    day_finding: QaFinding | None = None  # qa.time.date: the dates the log's day overruled

    @property
    def has_time(self) -> bool:
        return not self.how.startswith("no UTC")


_kept: dict[tuple[str, str, float | None], Prepass] | None = None


@contextlib.contextmanager
def kept() -> Iterator[None]:
    """Within it, each capture's pre-pass is made once and kept; it is dropped when the block ends."""
    global _kept
    outer, _kept = _kept, ({} if _kept is None else _kept)
    try:
        with parsed_once():  # and each line parsed once
            yield
    finally:
        _kept = outer


def prepass(path: str | Path, checksum: str = "strict", day: float | None = None) -> Prepass:
    """Read ``path``'s lines, time them and find its track (once per ``kept()`` block). ``day``: the
    UNIX time of the UTC midnight the log starts on, for a log whose sentences carry no date."""
    key = (str(path), checksum, day)
    if _kept is not None and key in _kept:
        return _kept[key]
    notes: list[str] = []
    lines = capture_lines(path, notes)
    parsed = _time_lines(lines, checksum)  # read once for the times and the track
    times, how, found = line_times(lines, checksum, day, parsed)
    seed = track_seed(_fixes(s for _, s in parsed)) if not how.startswith("no UTC") else None
    out = Prepass(lines, notes, times, how, seed, found)
    if _kept is not None:
        _kept[key] = out
    return out


def nmea_line_times(
    lines: list[bytes], checksum: str = "strict", day: float | None = None
) -> tuple[list[float], str]:
    """A UNIX time for every line (see the module docstring) and how it was found; ``day`` (the UTC
    midnight the log starts on, `import --date`) dates a log whose sentences carry no date."""
    times, how, _ = line_times(lines, checksum, day)
    return times, how


@dataclass(frozen=True)
class Dated:
    """One dated sentence: the log's first midnight its date implies, its own date, what vouches
    for it (FIX, NO_FIX, UNCONFIRMED) and whether its time of day is within MIDNIGHT_S of midnight."""

    base: int  # days since 1970-01-01
    own: int
    kind: str
    stype: str
    near_midnight: bool


def _fix_state(s) -> bool | None:  # type: ignore[no-untyped-def]
    """Whether a position sentence says its receiver has a fix (None: not a position sentence)."""
    if s.type == "GGA":
        return bool(s.data.get("quality"))
    if s.type in ("RMC", "GLL"):
        return s.data.get("status") == "A"
    return None


def _time_lines(lines: list[bytes], checksum: str) -> list[tuple[int, Sentence]]:
    """(line, sentence) of every valid sentence read from a line naming a time type (TIME_TYPES,
    which hold the POSITION_TYPES)."""
    parser = NmeaParser(checksum)
    out = []
    for i, line in enumerate(lines):
        if not any(k in line for k in TIME_TYPES):
            continue
        s = parser.parse(line)
        if s is not None and s.valid:
            out.append((i, s))
    return out


def _time_sentences(
    parsed: list[tuple[int, Sentence]],
) -> tuple[list[tuple[int, float]], list[tuple[int, float, str, str]]]:
    """(line, time of day) of every time sentence, and (index into the first, UTC, kind, type) of
    those that carry a date (``parsed``: ``_time_lines``)."""
    tods: list[tuple[int, float]] = []
    dated: list[tuple[int, float, str, str]] = []
    has_fix: dict[str, bool] = {}  # talker -> whether its last position sentence had a fix
    for i, s in parsed:
        fix = _fix_state(s)
        if fix is not None:
            has_fix[s.talker] = fix
        if s.data.get("tod") is None:
            continue
        if s.data.get("utc") is not None:
            if s.type == "RMC":
                kind = FIX if fix else NO_FIX
            else:  # ZDA: as good as its receiver's last position
                known = has_fix.get(s.talker)
                kind = UNCONFIRMED if known is None else FIX if known else NO_FIX
            dated.append((len(tods), s.data["utc"], kind, s.type))
        tods.append((i, s.data["tod"]))
    return tods, dated


def line_times(
    lines: list[bytes],
    checksum: str = "strict",
    day: float | None = None,
    parsed: list[tuple[int, Sentence]] | None = None,
) -> tuple[list[float], str, QaFinding | None]:
    """``nmea_line_times`` and the ``qa.time.date`` finding of what the log's day overruled
    (``parsed``: the lines' ``_time_lines``, when the caller has them)."""
    tods, past_at, dated = _dated(lines, checksum, parsed)
    n = len(lines)
    if not tods:
        return [float(i) for i in range(n)], "no UTC in the file: 1 s per line from 1970-01-01", None
    date0, note, finding = log_day(dated)
    base = date0 if date0 is not None else (day or 0.0)
    anchors: list[tuple[int, float]] = []
    for (i, tod), gone in zip(tods, past_at, strict=True):
        t = base + gone + tod
        if anchors and not (anchors[-1][1] < t <= anchors[-1][1] + 3600.0):
            continue  # not moving forward, or a corrupt stamp
        anchors.append((i, t))
    how = "UTC anchors from RMC/GGA/GLL/ZDA" + date_note(date0, day) + note
    return _spread(anchors, n), how, finding


def _dated(
    lines: list[bytes], checksum: str, parsed: list[tuple[int, Sentence]] | None = None
) -> tuple[list[tuple[int, float]], list[float], list[Dated]]:
    """(line, time of day) of every time sentence, the days gone by since the first one at each
    (midnights crossed), and every dated sentence as a Dated."""
    tods, dated_at = _time_sentences(_time_lines(lines, checksum) if parsed is None else parsed)
    past_at: list[float] = []
    past, prev_tod = 0.0, None
    for _, tod in tods:
        if prev_tod is not None and tod < prev_tod - DAY / 2:
            past += DAY  # past midnight
        past_at.append(past)
        prev_tod = tod
    dated = []
    for k, utc, kind, stype in dated_at:
        own = round((utc - tods[k][1]) / DAY)
        near = min(tods[k][1], DAY - tods[k][1]) <= MIDNIGHT_S
        dated.append(Dated(own - round(past_at[k] / DAY), own, kind, stype, near))
    return tods, past_at, dated


def log_date(lines: list[bytes], checksum: str = "strict") -> float | None:
    """The UTC midnight the log starts on, from its valid fixes (None: no date to trust), as
    ``line_times`` finds it (bench/inject_sentences.py dates an injected log with it)."""
    return log_day(_dated(lines, checksum)[2])[0]


def _spread(anchors: list[tuple[int, float]], n: int) -> list[float]:
    """A time for each of ``n`` lines: the anchors' times, spread evenly between them."""
    if len(anchors) >= 2 and anchors[-1][0] > anchors[0][0]:
        rate = (anchors[-1][1] - anchors[0][1]) / (anchors[-1][0] - anchors[0][0])
    else:
        rate = 1.0
    times = [0.0] * n
    k = 0
    for i in range(n):
        while k + 1 < len(anchors) and anchors[k + 1][0] <= i:
            k += 1
        i0, t0 = anchors[k]
        if i < i0:
            times[i] = t0 - (i0 - i) * rate
        elif k + 1 < len(anchors):
            i1, t1 = anchors[k + 1]
            times[i] = t0 + (t1 - t0) * (i - i0) / (i1 - i0)
        else:
            times[i] = t0 + (i - i0) * rate
    return times


def log_day(dated: list[Dated]) -> tuple[float | None, str, QaFinding | None]:
    """The UTC midnight the log starts on (None: no date to trust), the note on what it overruled
    ('' when nothing) and the finding that says so (see the module docstring)."""
    valid = [d for d in dated if d.kind == FIX] or [d for d in dated if d.kind == UNCONFIRMED]
    if not valid:
        if not dated:
            return None, "", None
        what = _groups(dated, None)
        note = f"; not used: {what} (a date without a fix never dates a log)"
        return None, note, _finding(None, 0, 0, dated, note[2:])
    votes = Counter(d.base for d in valid)
    best = votes.most_common(1)[0][0]
    agree = [d for d in valid if _agrees(d, best)]
    overruled = [d for d in dated if not _agrees(d, best)]
    if not overruled:
        return best * DAY, "", None
    source = "valid fixes" if valid[0].kind == FIX else "ZDA without a position to vouch for it"
    note = (
        f"; the day {iso(best * DAY)} from {len(agree)} {source}, overruling "
        f"{_groups(overruled, best)}"
    )
    return best * DAY, note, _finding(best, len(agree), len(valid), overruled, note[2:])


def _agrees(d: Dated, best: int) -> bool:
    return d.base == best or (d.near_midnight and abs(d.base - best) == 1)


def _groups(dated: list[Dated], best: int | None) -> str:
    """'24 RMC without a fix dated 2009-02-21' for each kind, type and day, joined."""
    groups: Counter[tuple[str, str, int]] = Counter((d.kind, d.stype, d.base) for d in dated)
    own: dict[tuple[str, str, int], set[int]] = {}
    for d in dated:
        own.setdefault((d.kind, d.stype, d.base), set()).add(d.own)
    kinds = {FIX: "valid {}", NO_FIX: "{} without a fix", UNCONFIRMED: "{} with no fix to vouch"}
    parts, put = [], set()
    for (kind, stype, b), count in groups.most_common():
        days = sorted(own[(kind, stype, b)])
        parts.append(f"{count} {kinds[kind].format(stype)} dated {_span(days)}")
        put |= {day - b + best for day in days} if best is not None else set()
    out = ", ".join(parts)
    if best is not None:
        out += f" (their rows kept, put on {_span(sorted(put))})"
    return out


def _span(days: list[int]) -> str:
    """'2009-02-21', or '2009-02-21 to 2009-02-22' (days since 1970-01-01, sorted)."""
    return iso(days[0] * DAY) + (f" to {iso(days[-1] * DAY)}" if len(days) > 1 else "")


def _finding(
    best: int | None, agree: int, valid: int, overruled: list[Dated], message: str
) -> QaFinding:
    """``qa.time.date``: red when no date could be trusted or the valid fixes' day is in doubt."""
    against = sum(d.kind == FIX for d in overruled)
    verdict = "red" if best is None or agree < SURE_SHARE * valid else "yellow"
    fix = (
        "applied: every row is dated by the valid fixes' day; give --date YYYY-MM-DD for a log "
        "without one"
        if best is not None
        else "the log has no valid date: give the day with --date YYYY-MM-DD"
    )
    extra = {
        "day": iso(best * DAY) if best is not None else "",
        "agreeing": str(agree),
        "valid_dated": str(valid),
        "overruled_valid": str(against),
        "overruled_without_fix": str(sum(d.kind == NO_FIX for d in overruled)),
        "overruled_unconfirmed": str(sum(d.kind == UNCONFIRMED for d in overruled)),
    }
    return QaFinding(
        "time", "date", verdict, message, value=float(len(overruled)), unit="sentences",
        threshold=f"the day most valid fixes give; in doubt (red) when under "
        f"{SURE_SHARE:.0%} of them agree",
        evidence="RMC status and the fix state of the ZDA's receiver; dates one day off within "
        f"{MIDNIGHT_S:g} s of midnight agree",
        fix=fix, applied=best is not None, extra=extra,
    )  # fmt: skip


def iso(t: float) -> str:
    """The UTC day of a UNIX time, YYYY-MM-DD."""
    return time.strftime("%Y-%m-%d", time.gmtime(t))


def date_note(date0: float | None, day: float | None) -> str:
    """Where the log's day came from: its own RMC or ZDA (and a --date that disagrees, not used), the
    user's --date, or nowhere (1970-01-01, and what that day gets wrong)."""
    if date0 is not None:
        if day is not None and iso(day) != iso(date0):
            return f"; the file's own date ({iso(date0)}) is used, not --date {iso(day)}"
        return ""
    if day is not None:
        return f", no date in the file: the day from --date, {iso(day)}"
    return (
        ", no date in the file: 1970-01-01 (the magnetic declination, tides and --at need the day: "
        "give it with --date YYYY-MM-DD)"
    )


def position_seed(
    lines: list[bytes], checksum: str = "strict"
) -> tuple[float, float, float] | None:
    """(lat, lon, radius m) of the boat's track from every valid fix in ``lines``, or None."""
    parser = NmeaParser(checksum)
    sentences = (parser.parse(line) for line in lines if any(k in line for k in POSITION_TYPES))
    return track_seed(_fixes(s for s in sentences if s is not None and s.valid))


def _fixes(sentences: Iterable[Sentence]) -> list[tuple[float, float]]:
    """(lat, lon) of each valid sentence that is a position with a fix (RMC, GGA, GLL: the only
    types with a position), in order."""
    fixes = []
    for s in sentences:
        if s.data.get("lat") is None or s.data.get("lon") is None:
            continue
        if s.type == "GGA" and not s.data.get("quality"):
            continue
        if s.type != "GGA" and s.data.get("status") != "A":
            continue
        fixes.append((s.data["lat"], s.data["lon"]))
    return fixes


def why_no_time(lines: list[bytes], name: str, checksum: str = "strict") -> str:
    """The one line for a capture from which no UTC was read: what rejected its time sentences."""
    parser = NmeaParser(checksum)
    kinds: Counter[str] = Counter()
    for line in lines:
        hit = next((k for k in TIME_TYPES if k in line), None)
        if hit is None:
            continue
        s = parser.parse(line)
        if s is not None and not s.valid:
            kinds[hit[:3].decode()] += 1
    if not kinds:
        return f"{name}: no time in this log (no NMEA RMC, GGA, GLL or ZDA with UTC)"
    which = ", ".join(f"{n} {k}" for k, n in kinds.most_common())
    reasons = ", ".join(f"{r} {n}" for r, n in parser.rejected.most_common())
    out = f"{name}: no time accepted from this log: its {which} lines were all rejected ({reasons})"
    found = nmea_checksum.systematic(parser.variants, parser.rejected["bad_checksum"])
    if found and checksum == "strict":
        variant, n = found[0]
        out += (
            f"; {n} of them have their checksum computed {nmea_checksum.describe(variant)}, a "
            "systematic variant: import with --nmea-checksum lenient to accept them"
        )
    return out


def finding_notes(findings: list) -> list[str]:
    """The import's note for each quality finding that is not green (its one line)."""
    return [f.message for f in findings if f.verdict != "green"]
