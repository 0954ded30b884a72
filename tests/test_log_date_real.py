"""Issue 60, item 5: the day of a log comes from its valid fixes.

A receiver dates its sentences by its own clock until its first fix: a real log opened with 11 RMC of
status V dated 2009-02-21 and then 31,000 valid fixes of 2014-07-12, and was dated 2009-02-21 whole
(its declination, its tide and every `--at` on the wrong day, and nothing said). The shared logs' own
invalid sentences carry the right date, so the case is built from them at NMEA level: their first RMC
get status V and an older date, the checksum recomputed. What the test expects is read from the built
lines themselves (the valid RMC's own dates, parsed here), never from the code's output.
"""

from __future__ import annotations

import calendar
import gzip
import json
import math
import time
from collections import Counter
from functools import reduce

import pytest
from forcemap.host.cli import main
from forcemap.host.convert.nmea_prepass import line_times

from tests.tools import csv_rows, real_data

DAY = 86400
OLD = "2009-02-21"  # the receiver's own date in the real case
FLENSBURG = "nmea/irene/irene_2013-08-03_flensburg.nmea"  # RMC and GLL, no ZDA
SFBAY = "nmea/sfbay/swift-day1.nmea.gz"  # opens with 24 real RMC of status V (no fix)
ZEUS = "nmea/bundg_zeus_9.log"  # RMC, GGA, GLL and ZDA of one receiver


# --- NMEA, read and written here, independently of forcemap's parser ----------------------------------


def _checksum(body: bytes) -> int:
    return reduce(lambda a, c: a ^ c, body, 0)


def _fields(line: bytes) -> list[bytes] | None:
    """The fields of a sentence whose checksum holds (the address first), else None."""
    start, star = line.find(b"$"), line.rfind(b"*")
    if start < 0 or star < start:
        return None
    body = line[start + 1 : star]
    try:
        if int(line[star + 1 : star + 3], 16) != _checksum(body):
            return None
    except ValueError:
        return None
    return body.split(b",")


def _with(line: bytes, changes: dict[int, bytes]) -> bytes:
    """``line`` with some fields replaced (index: 0 is the address) and its checksum recomputed."""
    f = _fields(line)
    assert f is not None, line
    for i, v in changes.items():
        f[i] = v
    body = b",".join(f)
    return b"$" + body + b"*%02X" % _checksum(body)


def _ddmmyy(iso: str) -> bytes:
    y, m, d = iso.split("-")
    return f"{d}{m}{y[2:]}".encode()


def _is(line: bytes, stype: bytes) -> bool:
    return line.startswith(b"$") and line[3:7] == stype + b","


def _utc(f: list[bytes]) -> float | None:
    """The UNIX time of an RMC's fields (time and date), else None."""
    tod, date = f[1].decode(), f[9].decode()
    if len(tod) < 6 or len(date) != 6:
        return None
    yy = int(date[4:])
    day = calendar.timegm((2000 + yy if yy < 80 else 1900 + yy, int(date[2:4]), int(date[:2]), 0, 0, 0))
    return day + int(tod[:2]) * 3600 + int(tod[2:4]) * 60 + float(tod[4:])


def _valid_rmc(lines: list[bytes]) -> list[float]:
    """The UTC of every RMC of status A whose checksum holds, in order."""
    out = []
    for ln in lines:
        f = _fields(ln) if b"RMC," in ln else None
        if f is not None and f[0].endswith(b"RMC") and len(f) >= 10 and f[2] == b"A":
            t = _utc(f)
            if t is not None:
                out.append(t)
    return out


def _read(name: str, n: int | None = None) -> list[bytes]:
    path = real_data() / name
    data = gzip.open(path).read() if path.suffix == ".gz" else path.read_bytes()
    return data.splitlines()[:n]


def _redate_first_rmc(lines: list[bytes], n: int, status: bytes, iso: str) -> list[bytes]:
    """The first ``n`` RMC given ``status`` and the date ``iso``."""
    out, k = list(lines), 0
    for i, ln in enumerate(out):
        if k < n and _is(ln, b"RMC"):
            out[i], k = _with(ln, {2: status, 9: _ddmmyy(iso)}), k + 1
    assert k == n
    return out


def _iso(t: float) -> str:
    return time.strftime("%Y-%m-%d", time.gmtime(t))


def _one_day(ts: list[float]) -> str:
    days = Counter(_iso(t) for t in ts)
    assert len(days) == 1, days
    return next(iter(days))


def _date_findings(report: dict) -> list[dict]:
    return [f for f in report["categories"].get("time", {}).get("findings", []) if f["check"] == "date"]


# --- the built case through `import`, `export` and `check` -------------------------------------------


@pytest.fixture(scope="module")
def flensburg(tmp_path_factory):
    """The first 8,000 lines (about 15 min) of the Flensburg race, its first 11 RMC made status V and
    dated 2009-02-21: imported, exported and checked as a user would."""
    folder = tmp_path_factory.mktemp("date")
    lines = _redate_first_rmc(_read(FLENSBURG, 8000), 11, b"V", OLD)
    built = folder / "flensburg_v_2009.nmea"
    built.write_bytes(b"\n".join(lines) + b"\n")
    return folder, built, lines


def test_a_log_opening_with_invalid_rmc_of_an_older_date_gets_its_valid_fixes_day(flensburg, capsys):
    from forcemap.host.qa.report import log_findings
    from pyIGRF14 import igrf_value

    folder, built, lines = flensburg
    fixes = _valid_rmc(lines)
    day = _one_day(fixes)  # the valid fixes' own day, read here
    assert day != OLD
    mcap, table = folder / "built.mcap", folder / "built.csv"
    assert main(["import", str(built), "-o", str(mcap)]) == 0
    out = capsys.readouterr().out
    said = [ln for ln in out.splitlines() if OLD in ln]
    assert len(said) == 1, out  # one clear line: what was overruled, counted, and the day it got
    assert "11 RMC without a fix dated 2009-02-21" in said[0] and day in said[0], said
    assert f"from {len(fixes)} valid fixes" in said[0], said

    # every row on the valid fixes' day, within their span; none dropped (the V lines' rows kept)
    assert main(["export", str(mcap), "-o", str(table)]) == 0
    capsys.readouterr()
    header, rows = csv_rows(table)
    t = [float(r[header.index("t")]) for r in rows]
    assert _one_day(t) == day
    assert min(fixes) - 60 <= min(t) and max(t) <= max(fixes) + 60

    # the magnetic heading is turned true with the declination of that day, not of 2009-02-21
    decl = next(f for f in log_findings(mcap) if f.check == "declination")
    assert _iso(float(decl.extra["utc_s"])) == day
    lat, lon, when = float(decl.extra["lat"]), float(decl.extra["lon"]), float(decl.extra["utc_s"])

    def igrf(t: float) -> float:
        year = 1970 + t / (365.2425 * DAY)
        return float(igrf_value(lat, lon % 360.0, 0.0, year)[0])

    old_t = calendar.timegm((2009, 2, 21, 0, 0, 0)) + when % DAY
    assert decl.value == pytest.approx(igrf(when), abs=0.02)
    assert abs(igrf(when) - igrf(old_t)) > 0.3  # the wrong day would have shown (0.7 deg here)

    # `check` says it, in its text and its JSON, with the counts
    report = folder / "check.json"
    assert main(["check", str(built), "--json", str(report)]) == 0
    text = capsys.readouterr().out
    assert any("date" in ln and OLD in ln and day in ln for ln in text.splitlines()), text
    (f,) = _date_findings(json.loads(report.read_text()))
    assert f["verdict"] == "yellow" and f["applied"]
    assert f["extra"]["day"] == day
    assert int(f["extra"]["overruled_without_fix"]) == 11
    assert int(f["extra"]["agreeing"]) == len(fixes) and int(f["extra"]["overruled_valid"]) == 0


def test_a_minority_of_valid_fixes_with_a_wrong_year_is_overruled_and_said(flensburg, capsys):
    """The first 40 RMC keep status A but say a year earlier: the majority's day wins, whichever
    comes first, and `check` counts the valid fixes it overruled."""
    folder, _, _ = flensburg
    lines = _redate_first_rmc(_read(FLENSBURG, 8000), 40, b"A", "2012-08-03")
    built = folder / "flensburg_minority_2012.nmea"
    built.write_bytes(b"\n".join(lines) + b"\n")
    dates = Counter(_iso(t) for t in _valid_rmc(lines))
    (day, most), (wrong, fewer) = dates.most_common()
    assert wrong == "2012-08-03" and fewer == 40 < most
    times, how, _ = line_times(lines)
    assert _one_day(times) == day
    report = folder / "minority.json"
    assert main(["check", str(built), "--json", str(report)]) == 0
    text = capsys.readouterr().out
    assert any("40 valid RMC dated 2012-08-03" in ln and day in ln for ln in text.splitlines()), text
    (f,) = _date_findings(json.loads(report.read_text()))
    assert f["verdict"] == "yellow"
    assert (int(f["extra"]["agreeing"]), int(f["extra"]["overruled_valid"])) == (most, 40)


# --- the day itself, on more real logs (the pre-pass alone: no pipeline) ------------------------------


def test_the_real_no_fix_sentences_of_sfbay_redated_do_not_date_it():
    """swift-day1 opens with real no-fix RMC (status V): given the real case's older date, they
    no longer date the log; every line, theirs too, is on the valid fixes' day."""
    lines = _read(SFBAY, 3000)
    no_fix = [i for i, ln in enumerate(lines) if _is(ln, b"RMC") and _fields(ln) and _fields(ln)[2] == b"V"]
    built = list(lines)
    for i in no_fix:
        built[i] = _with(lines[i], {9: _ddmmyy(OLD)})
    day = _one_day(_valid_rmc(built))
    times, how, finding = line_times(built)
    assert _one_day(times) == day
    assert f"{len(no_fix)} RMC without a fix dated {OLD}" in how, how
    assert finding is not None and int(finding.extra["overruled_without_fix"]) == len(no_fix)
    # before: the same lines as recorded give the same times, and nothing to say
    plain, plain_how, none = line_times(lines)
    assert plain == times and none is None and OLD not in plain_how


def test_only_dates_without_a_fix_never_date_a_log():
    """The sfbay log's first 300 lines, before its first fix, their RMC dated 2009-02-21: no day from
    them (1970-01-01 and the finding says to give --date); --date gives the day."""
    lines = _read(SFBAY, 300)
    assert not _valid_rmc(lines)
    n = sum(_is(ln, b"RMC") for ln in lines)
    built = _redate_first_rmc(lines, n, b"V", OLD)
    times, how, finding = line_times(built)
    assert _one_day(times) == "1970-01-01"
    assert f"not used: {n} RMC without a fix dated {OLD}" in how, how
    assert finding is not None and finding.verdict == "red" and "--date" in finding.fix
    day = calendar.timegm((2014, 5, 17, 0, 0, 0))
    times, how, _ = line_times(built, day=day)
    assert _one_day(times) == "2014-05-17" and "the day from --date" in how


def test_a_zda_of_a_receiver_without_a_fix_does_not_date_the_log():
    """bundg_zeus_9's receiver (RMC, GGA, GLL, ZDA on one talker) made to start without a fix: its
    first 20 RMC status V, GGA quality 0 and GLL V meanwhile, and their RMC and ZDA dated 2009-02-21."""
    lines = _read(ZEUS)
    last = [i for i, ln in enumerate(lines) if _is(ln, b"RMC")][19]
    built, n_zda = [], 0
    for i, ln in enumerate(lines):
        if i <= last and _fields(ln) is not None:
            if _is(ln, b"RMC"):
                ln = _with(ln, {2: b"V", 9: _ddmmyy(OLD)})
            elif _is(ln, b"GGA"):
                ln = _with(ln, {6: b"0"})  # fix quality
            elif _is(ln, b"GLL"):
                ln = _with(ln, {6: b"V"})  # status
            elif _is(ln, b"ZDA"):  # $GPZDA,hhmmss.ss,dd,mm,yyyy,...
                ln, n_zda = _with(ln, {2: b"21", 3: b"02", 4: b"2009"}), n_zda + 1
        built.append(ln)
    assert n_zda >= 15
    day = _one_day(_valid_rmc(built))
    times, how, finding = line_times(built)
    assert _one_day(times) == day
    assert f"20 RMC without a fix dated {OLD}" in how, how
    assert f"ZDA without a fix dated {OLD}" in how, how
    assert finding is not None and finding.value == 20 + n_zda  # every one counted


def _shift(lines: list[bytes], by_s: float, late_rollover: bool = False) -> list[bytes]:
    """Every time sentence moved ``by_s`` later, its date with it (RMC and ZDA); ``late_rollover``:
    the first RMC after midnight keeps the day before, as a receiver that rolls its date late."""
    out, rolled = [], False
    for ln in lines:
        f = _fields(ln)
        stype = f[0][2:].decode() if f else ""
        field = {"RMC": 1, "GGA": 1, "ZDA": 1, "GLL": 5}.get(stype)
        if f is None or field is None or len(f[field]) < 6:
            out.append(ln)
            continue
        tod = f[field].decode()
        if stype == "RMC":
            t0 = _utc(f)
        elif stype == "ZDA":
            t0 = calendar.timegm((int(f[4]), int(f[3]), int(f[2]), 0, 0, 0))
            t0 += int(tod[:2]) * 3600 + int(tod[2:4]) * 60 + float(tod[4:])
        else:
            t0 = calendar.timegm((2018, 8, 20, 0, 0, 0))  # the log's day (its RMC say so)
            t0 += int(tod[:2]) * 3600 + int(tod[2:4]) * 60 + float(tod[4:])
        t = t0 + by_s
        frac = tod[6:]
        hms = f"{int(t % DAY) // 3600:02d}{int(t % DAY) // 60 % 60:02d}{int(t % 60):02d}{frac}"
        changes = {field: hms.encode()}
        iso = _iso(t)
        if stype == "RMC":
            if late_rollover and not rolled and t % DAY < 5:
                iso, rolled = _iso(t - DAY), True
            changes[9] = _ddmmyy(iso)
        elif stype == "ZDA":
            y, m, d = iso.split("-")
            changes.update({2: d.encode(), 3: m.encode(), 4: y.encode()})
        out.append(_with(ln, changes))
    return out


@pytest.mark.parametrize("late", [False, True])
def test_a_log_across_midnight_is_one_day_and_the_next_with_nothing_to_say(late):
    """bundg_zeus_9 moved to end after 00:00 UTC: the dates roll over with the times of day, which
    is no disagreement (nor a receiver that rolls its date over a second late)."""
    lines = _read(ZEUS)
    fixes = _valid_rmc(lines)
    to_midnight = (math.floor(fixes[0] / DAY) + 1) * DAY - (fixes[0] + fixes[-1]) / 2
    built = _shift(lines, to_midnight, late)
    times, how, finding = line_times(built)
    assert finding is None and "overrul" not in how, how
    assert Counter(_iso(t) for t in times).keys() == {"2018-08-20", "2018-08-21"}
    steps = [b - a for a, b in zip(times, times[1:], strict=False)]
    assert min(steps) >= 0 and max(steps) < 5.0
    assert times[-1] - times[0] == pytest.approx(fixes[-1] - fixes[0], abs=5.0)


def test_valid_fixes_split_near_half_and_half_leave_the_day_in_doubt():
    """When 45 % of the valid fixes say another year the majority still dates the rows, and the
    finding is red: the day is in doubt."""
    lines = _read(FLENSBURG, 8000)  # RMC its only dated sentence
    n = len(_valid_rmc(lines))
    k = int(0.45 * n)
    built = _redate_first_rmc(lines, k, b"A", "2012-08-03")
    times, how, finding = line_times(built)
    assert _one_day(times) == "2013-08-03" == _one_day(_valid_rmc(lines))
    assert f"{k} valid RMC dated 2012-08-03" in how, how
    assert finding is not None and finding.verdict == "red"
    assert int(finding.extra["agreeing"]) == n - k


def test_the_injector_dates_a_built_log_as_the_importer_does():
    """bench/inject_nmea.py writes its truth on the day the import gives the log (its own reading of
    the sentences, by the same rule): on the built cases too, not on the no-fix sentences' day."""
    from forcemap.host.convert.nmea_prepass import log_date

    from bench.inject_sentences import log_date as injector_date

    cases = [
        _read(ZEUS),
        _redate_first_rmc(_read(FLENSBURG, 8000), 11, b"V", OLD),
        _redate_first_rmc(_read(FLENSBURG, 8000), 40, b"A", "2012-08-03"),
    ]
    for lines in cases:
        day = log_date(lines)
        assert day is not None and _iso(day) == _one_day(_valid_rmc(lines)[-10:])
        assert injector_date(lines) == day
