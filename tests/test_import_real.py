"""Every real capture in tests/data/real goes through `forcemap import`; the counts are pinned.

The NMEA captures go through the NMEA path and the tlogs through the MAVLink path. Each NMEA capture
is imported once per test run and shared with the other modules that read it (tests/real_cases.py:
the sfbay log alone takes about 100 s of CPU); its MCAP log is counted from the file's summary. The
first 3000 packets of a tlog are written to real MCAP and read back.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest
from forcemap.host.cli import main
from forcemap.host.convert.importers import import_file, tlog_records, why_no_samples
from forcemap.host.log.mcap import McapLog, read_messages

from tests.real_cases import topic_counts
from tests.tools import real_data

REAL = real_data()

NMEA = {
    "PacCupStartNMEA.txt": (
        59887,
        59887,
        {
            "DBT": 2212,
            "GGA": 1106,
            "GLL": 1105,
            "GSA": 2212,  # in "other" until GSA's fix type and HDOP ranked receivers (issue 20)
            "HDM": 2212,
            "MTW": 2211,
            "RMC": 1105,
            "VHW": 2212,
            "VTG": 1106,
            "VWR": 2211,
            "ZDA": 1106,
            "other": 41089,
        },
        {},
    ),
    "plaka.log": (
        116000,
        116000,
        {
            "DBT": 7250,
            "GLL": 7250,
            "HDM": 7250,
            "HDT": 14500,
            "MWD": 7250,
            "MWV": 7250,
            "VHW": 7250,
            "VTG": 7250,
            "ZDA": 7250,
            "other": 43500,
        },
        {},
    ),
    "bundg_zeus_9.log": (
        5007,
        4999,  # 8 comment lines
        {
            "DBT": 148,
            "DPT": 149,
            "GGA": 138,
            "GLL": 147,
            "GSA": 144,
            "HDG": 1457,
            "MTW": 149,
            "MWD": 150,
            "MWV": 300,
            "RMC": 146,
            "VHW": 150,
            "VTG": 148,
            "ZDA": 154,
            "XDR": 148,  # in "other" until the hull's heel and trim were read (issue 37)
            "other": 1471,
        },
        {},
    ),
    "NeutronDance.log": (
        19493,
        19493,
        {
            "DBT": 3702,
            "DPT": 5208,
            "GGA": 322,
            "GSA": 59,  # 61 lines hold a GPGSA: 59 whole, one cut to its address, one in a spliced line
            "MWV": 1354,
            "RMC": 1428,
            "VHW": 1692,
            "other": 800,
        },
        {
            "bad_checksum": 939,
            "field_count": 25,
            "no_checksum": 638,
            "no_start": 27,
            "parse_error": 3,
            "spliced": 3296,
        },
    ),
}
# Irene (nmea/irene/PROVENANCE.md): counted by plain string splitting, the checksum's XOR by hand, and
# each sentence's address against the types forcemap reads (nmea_fields.SPECS; the rest is "other")
IRENE = {
    "irene_2008-08-20_geneva.nmea": (
        46800,
        46800,
        {
            "DPT": 4873,
            "GLL": 4873,
            "HDG": 4874,
            "MTW": 4874,
            "MWV": 9748,  # R and T alternate
            "RMC": 4871,
            "VHW": 4874,
            "VWR": 4874,
            "other": 2939,  # IIRMB
        },
        {},
    ),
    # with --nmea-checksum lenient (NMEA_OPTIONS): 37,546 lines have their checksum computed over the
    # address only, 1,930 the standard way (1,474 RMB and VLW, 456 DPT whose fields XOR to 0);
    # 4 spliced lines match neither
    "irene_2013-07-31_flensburg_checksums.nmea": (
        39480,
        39480,
        {
            "DPT": 3811,
            "GLL": 3703,
            "HDG": 3798,
            "MTW": 3822,
            "MWV": 7669,
            "RMC": 3712,
            "VHW": 3792,
            "VWR": 3803,
            "other": 5366,  # IIVLW 3,802, IIRMB 1,564
        },
        {"bad_checksum": 4},
    ),
    "irene_2013-08-03_flensburg.nmea": (
        128574,
        128574,
        {
            "DPT": 12260,
            "GLL": 12012,  # IIGLL 11,989, and 23 spliced under GP and GI
            "HDG": 12275,
            "MTW": 12290,
            "MWV": 24417,
            "RMC": 11870,  # IIRMC 11,832, and 38 spliced under GP and GI
            "VHW": 12196,
            "VWR": 12205,
            "other": 19048,  # IIVLW, GPRMB and the spliced ids that do not exist (GPRMW ...)
        },
        {"no_start": 1},  # line 9,643: a GPRMB that lost its $
    ),
    "irene_2014-06-27_geneva.nmea": (
        75623,
        75623,
        {
            "DPT": 7562,
            "GLL": 7563,
            "HDG": 7563,
            "MTW": 7563,
            "MWV": 15124,
            "RMC": 7562,
            "VHW": 7563,
            "VWR": 7561,
            "other": 7562,  # IIVLW
        },
        {},
    ),
}
NMEA.update(IRENE)
# sfbay/PROVENANCE.md, counted the same way; gzipped, read as the file it holds. Rejected by hand: 13,094
# lines without a checksum (13,091 $PSCI heartbeats, 2 bare "$", 1 cut GLL), 471 with bytes that are
# not printable ASCII (NULs before a second $, mostly on VTG), 10 "Log created by gybelog" lines and
# 2 checksums that fail (an MTW, a KIDBT)
NMEA["swift-day1.nmea.gz"] = (
    373525,
    373525,
    {
        "DBT": 26497,
        "GGA": 26500,
        "GLL": 26500,
        "GSA": 26500,
        "HDM": 26498,
        "MTW": 26494,
        "RMC": 26502,
        "VHW": 26501,
        "VTG": 26064,
        "VWR": 26494,
        "other": 95398,  # GSV, RMB, APB, BWR
    },
    {"bad_checksum": 2, "no_checksum": 13094, "no_start": 10, "not_ascii": 471},
)
NMEA_OPTIONS = {"irene_2013-07-31_flensburg_checksums.nmea": ["--nmea-checksum", "lenient"]}
# magnetic heading (HDG) and no variation in HDG or RMC: the declination is IGRF-14's, said once
NO_VARIATION = {n for n in IRENE if "2014" not in n} | {"swift-day1.nmea.gz"}
NO_MEASUREMENTS = "no measurements in this log"
TLOG = {
    "ardusub_2023-05-04_bluerov_small.tlog": (
        35916,
        35912,
        {"1/100/259": 1, "1/100/260": 1, "1/100/262": 1, "1/100/269": 1},
        792,
        NO_MEASUREMENTS,  # a BlueROV at a dock: GPS, but no sounder, log or wind sensor
    ),
    "ardusub_2023-04-18_bluerov_distance_sensor_badcrc.tlog": (
        52103,
        50136,
        {
            "1/194/132": 1949,
            "255/0/21": 6,
            "255/0/76": 4,
            "1/100/77": 4,
            "1/100/259": 1,
            "1/100/260": 1,
            "1/100/262": 1,
            "1/100/269": 1,
        },
        0,  # no GPS fix in this log
        "no position in this log",  # its sonar (DISTANCE_SENSOR, orientation 25) is read all the same
    ),
    "copter_2015-07-05_droneshare_flight.tlog": (
        76792,
        75477,
        {"255/0/142": 1314},
        2684,
        NO_MEASUREMENTS,
    ),
}


class CountingLog:
    """Stands in for McapLog: counts messages per topic."""

    def __init__(self, out=".", **kw):
        self.counts: Counter[str] = Counter()
        self.meta: dict[str, dict] = {}
        self.paths = [Path(out) / "in-memory.mcap"]
        self.path = self.paths[0]

    def write(self, topic, log_time_ns, message):
        self.counts[topic] += 1

    def metadata(self, name, data):
        self.meta[name] = data

    def close(self):
        pass


def test_every_real_file_is_covered():
    """Every data file under tests/data/real, in its folders (nmea/irene/ too), except adcp/: the
    ADCP readers' files, which tests/test_adcp.py::test_every_file_in_the_adcp_folder_is_read covers."""
    data = {
        p.name
        for p in REAL.rglob("*")
        if p.is_file()
        and p.relative_to(REAL).parts[0] not in ("adcp", "tides")
        and p.suffix.lower() not in (".md", ".csv")
    }
    assert data == set(NMEA) | set(TLOG) | {"ardusub_4.1_bluerov_small.BIN"} | set(COUNTED_ELSEWHERE)


# logs whose sentences are not yet counted by hand here, and the tests that read them whole; tides/ holds
# station constants, read by tests/test_reference_current.py
COUNTED_ELSEWHERE = {
    "duxbury.nmea.gz": "tests/test_qa_real.py (import, export, check), tests/test_sfbay_cross_day.py",
}


@pytest.mark.parametrize("name", sorted(NMEA))
def test_nmea_capture(name, real_case):
    records, lines, accepted, rejected = NMEA[name]
    built = real_case(next(REAL.rglob(name)).relative_to(REAL).as_posix())
    assert built.case.checksum == ("lenient" if name in NMEA_OPTIONS else "strict")
    rc, text = built.import_rc, built.import_text
    assert rc == 0, text
    said = [ln for ln in text.splitlines() if "magnetic heading without variation: IGRF-14" in ln]
    assert len(said) == (name in NO_VARIATION), text
    assert f"{records} lines (nmea)" in text
    assert f"{sum(accepted.values())} accepted {dict(sorted(accepted.items()))}" in text
    assert f"{sum(rejected.values())} rejected {dict(sorted(rejected.items()))}" in text
    counts = topic_counts(built.mcap)
    assert counts["/nmea/sentence"] == lines
    assert counts["/fix"] > 0 and counts["/depth"] > 0


@pytest.mark.parametrize("name", sorted(TLOG))
def test_tlog(name, tmp_path, capsys):
    """Counts pinned through the importer; the command says in one line why there are no samples
    (exit 2) and leaves no file."""
    packets, good, bad, gpi_fixes, reason = TLOG[name]
    path = REAL / "mavlink" / name
    log = CountingLog()
    res = import_file(path, log)
    c = res.counters["mavlink"]
    assert res.records == packets and c["messages"] == good
    assert c["bad_crc_by_sender_msgid"] == bad
    assert sum(n for t, n in log.counts.items() if t.startswith("/mavlink/")) == good
    assert log.counts["/boat/state"] == gpi_fixes
    assert log.counts["/samples"] == 0 and reason in why_no_samples(res)
    assert main(["import", str(path), "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and reason in err
    assert not list(tmp_path.iterdir())


def test_dataflash_without_gps_says_so_in_one_line(tmp_path, capsys):
    """The real ArduSub .BIN has no GPS: one line, exit 2, no file (with or without --from)."""
    path = REAL / "mavlink" / "ardusub_4.1_bluerov_small.BIN"
    for extra in ([], ["--from", "dataflash"]):
        assert main(["import", str(path), "-o", str(tmp_path), *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "no position in this log" in err
    assert not list(tmp_path.iterdir())
    log = CountingLog()
    res = import_file(path, log)
    assert res.format == "dataflash" and res.records == 7510  # as PROVENANCE.md counts them
    assert log.counts["/dataflash/ATT"] == 237 and log.counts["/fix"] == 0


def _gzip(src: Path, out: Path, keep: float = 1.0) -> Path:
    import gzip

    data = gzip.compress(src.read_bytes(), mtime=0)
    out.write_bytes(data[: int(len(data) * keep)])
    return out


def test_a_gzipped_capture_imports_as_the_file_it_holds(tmp_path):
    """Read through one streamed gunzip (forcemap.host.convert.capture_file): the same lines, the
    same counts and rows as the plain file, whatever its name."""
    src = REAL / "nmea" / "bundg_zeus_9.log"
    plain, gz = CountingLog(), CountingLog()
    a = import_file(src, plain)
    b = import_file(_gzip(src, tmp_path / "capture.dat"), gz)
    assert b.format == "nmea" and b.records == a.records == NMEA[src.name][0]
    assert b.counters["nmea"] == a.counters["nmea"] and gz.counts == plain.counts
    assert gz.counts["/samples"] > 100


def _prefixed(src: Path, out: Path, prefix) -> Path:
    """``src`` with ``prefix(i)`` put before each of its lines (a ``#`` comment kept as it is)."""
    lines = src.read_bytes().splitlines()
    out.write_bytes(
        b"\n".join(ln if ln[:1] == b"#" else prefix(i) + ln for i, ln in enumerate(lines)) + b"\n"
    )
    return out


@pytest.mark.parametrize(
    "prefix",
    [
        lambda i: f"2011-05-21 14:{i // 600 % 60:02d}:{i // 10 % 60:02d}.{i % 10}00 ".encode(),
        lambda i: f"{1305986400000 + 100 * i};N;".encode(),
        lambda i: b"\\s:logger,c:%d*00\\" % (1305986400 + i // 10),  # an NMEA 4 TAG block
    ],
    ids=["time stamp", "time and source", "TAG block"],
)
def test_a_loggers_prefix_before_each_sentence_is_left_aside_and_counted(prefix, tmp_path, capsys):
    """Loggers put their own time stamp, a source or an NMEA 4 TAG block before each sentence: the
    capture imports as the plain file does (its lines, counts and rows), and the note says how many
    lines had a prefix and what the first one was."""
    src = REAL / "nmea" / "bundg_zeus_9.log"
    plain, pre = CountingLog(), CountingLog()
    a = import_file(src, plain)
    path = _prefixed(src, tmp_path / "prefixed.log", prefix)
    b = import_file(path, pre)
    assert b.format == "nmea" and b.records == a.records == NMEA[src.name][0]
    assert b.counters["nmea"] == a.counters["nmea"] and pre.counts == plain.counts
    note = next(n for n in b.notes if "carry a prefix" in n)
    lines = src.read_bytes().splitlines()
    sentences = [i for i, ln in enumerate(lines) if ln[:1] != b"#"]
    assert f"{len(sentences):,} of {len(lines):,} lines carry a prefix" in note, note
    assert repr(prefix(sentences[0]).decode()[:40]) in note, note
    # what is no NMEA before or after its prefix is still not taken for a capture
    junk = tmp_path / "junk.txt"
    junk.write_text("".join(f"{i};N;hello {i}\n" for i in range(50)))
    assert main(["import", str(junk), "-o", str(tmp_path / "junk.mcap")]) == 2
    assert "not a format forcemap recognises" in capsys.readouterr().err


class FixTimes(CountingLog):
    """Counts messages per topic and keeps the times of the fixes."""

    def __init__(self, out=".", **kw):
        super().__init__(out, **kw)
        self.fix_s: list[float] = []

    def write(self, topic, log_time_ns, message):
        super().write(topic, log_time_ns, message)
        if topic == "/fix":
            self.fix_s.append(log_time_ns / 1e9)


def test_a_log_without_a_date_takes_its_day_from_date_and_says_so_without_it(tmp_path, capsys):
    """GGA and GLL carry the time of day, not the day: a log without RMC or ZDA has no date. With
    --date its fixes fall where the same log's own dates put them; without it they fall on
    1970-01-01, and the import says so and names --date (the declination and tides need the day)."""
    from forcemap.host.cli.pipeline_options import log_day

    src = REAL / "nmea" / "bundg_zeus_9.log"
    lines = src.read_bytes().splitlines()
    dateless = tmp_path / "dateless.log"
    dateless.write_bytes(b"\n".join(ln for ln in lines if ln[3:6] not in (b"RMC", b"ZDA")))
    plain, dated, undated = FixTimes(), FixTimes(), FixTimes()
    import_file(src, plain)
    b = import_file(dateless, dated, day=log_day("2018-08-20"))
    c = import_file(dateless, undated)
    assert dated.fix_s and len(dated.fix_s) == len(undated.fix_s)
    assert abs(min(dated.fix_s) - min(plain.fix_s)) < 2.0
    assert abs(max(dated.fix_s) - max(plain.fix_s)) < 2.0
    assert max(undated.fix_s) < 86400.0
    assert any("the day from --date, 2018-08-20" in n for n in b.notes), b.notes
    assert any("1970-01-01" in n and "--date YYYY-MM-DD" in n for n in c.notes), c.notes
    # a log's own date comes first; a --date that disagrees is named, not used
    again = FixTimes()
    d = import_file(src, again, day=log_day("2018-08-21"))
    assert again.fix_s == plain.fix_s
    assert any("the file's own date (2018-08-20) is used, not --date 2018-08-21" in n for n in d.notes)
    with pytest.raises(SystemExit) as e:
        main(["import", str(dateless), "--date", "20.8.2018", "-o", str(tmp_path / "x.mcap")])
    assert e.value.code == 2 and not (tmp_path / "x.mcap").exists()
    assert "'20.8.2018' is not a day (YYYY-MM-DD)" in capsys.readouterr().err


def test_a_gzipped_capture_cut_short_gives_what_it_holds_and_says_so(tmp_path, capsys):
    src = REAL / "nmea" / "bundg_zeus_9.log"
    cut = _gzip(src, tmp_path / "cut.log.gz", keep=0.6)
    assert main(["import", str(cut), "-o", str(tmp_path / "cut.mcap")]) == 0
    out = capsys.readouterr().out
    assert "the gzip stream ends early" in out, out
    n = int(out.split(": ", 1)[1].split(" lines", 1)[0])
    assert 0.3 * NMEA[src.name][0] < n < NMEA[src.name][0]  # about 60 % of the file's lines


def test_a_damaged_or_unsupported_gzip_is_one_line(tmp_path, capsys):
    src = REAL / "nmea" / "bundg_zeus_9.log"
    bad = bytearray(_gzip(src, tmp_path / "x.gz").read_bytes())
    bad[len(bad) // 2 : len(bad) // 2 + 64] = bytes(64)
    (tmp_path / "bad.log.gz").write_bytes(bytes(bad))
    dataflash = _gzip(REAL / "mavlink" / "ardusub_4.1_bluerov_small.BIN", tmp_path / "a.BIN.gz")
    for path, says in ((tmp_path / "bad.log.gz", "damaged gzip data"), (dataflash, "gunzip")):
        assert main(["import", str(path), "-o", str(tmp_path / "o.mcap")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and says in err, err
    assert not (tmp_path / "o.mcap").exists()


def test_bad_inputs_are_one_line_errors(tmp_path, capsys):
    junk = tmp_path / "junk.dat"
    junk.write_bytes(b"\x01\x02 hello")
    assert main(["import", str(junk), "-o", str(tmp_path)]) == 2
    assert main(["import", str(tmp_path / "missing.log"), "-o", str(tmp_path)]) == 2
    bad_cfg = tmp_path / "boat.toml"
    bad_cfg.write_text('[vane]\nvref = "x"\n')
    assert (
        main(
            [
                "import",
                str(junk),
                "--boat",
                str(bad_cfg),
                "--from",
                "nmea",
                "-o",
                str(tmp_path),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and "vane.vref" in err[2]


def test_tlog_to_mcap_round_trip(tmp_path, capsys):
    src = REAL / "mavlink" / "ardusub_2023-05-04_bluerov_small.tlog"
    data = src.read_bytes()
    end = 0
    for n, (_, pkt) in enumerate(tlog_records(data)):
        end = data.index(pkt, end) + len(pkt)
        if n == 2999:
            break
    part = tmp_path / "part.tlog"
    part.write_bytes(data[:end])
    with McapLog(tmp_path / "out", prefix="part") as log:
        res = import_file(part, log)
    assert res.records == 3000
    good, bad = res.counters["mavlink"]["messages"], res.counters["mavlink"]["bad_crc"]
    assert good + bad == 3000
    files = list((tmp_path / "out").glob("part-*.mcap"))
    assert len(files) == 1
    msgs = list(read_messages(files[0]))
    counts = Counter(m.topic for m in msgs)
    assert sum(n for t, n in counts.items() if t.startswith("/mavlink/")) == good
    assert counts["/fix"] > 0 and counts["/boat/state"] > 0 and counts["/diagnostics"] > 0
    fix = next(m.message for m in msgs if m.topic == "/fix")
    assert fix["latitude"] == pytest.approx(48.386, abs=0.01)
    # log times are the GCS receive times of 2023-05-04 (SYSTEM_TIME has no UTC in this log)
    assert all(1683200000e9 < m.log_time_ns < 1683300000e9 for m in msgs)


def test_paccup_true_wind_through_the_import_path():
    """The pipeline's own /wind/true from the capture matches OpenCPN's true wind (SOG along COG,
    which is forcemap's W = R + V) on the reference rows, within 0.1 kn and 1 deg."""
    import csv

    from forcemap.host.convert.importers import import_nmea
    from forcemap.host.decode.nmea import KNOT
    from forcemap.host.fuse.pipeline import ListSink
    from forcemap.host.vessel.geodesy import wrap_to_180

    sink = ListSink()
    import_nmea(REAL / "nmea" / "PacCupStartNMEA.txt", sink)
    line, by_line = 0, {}
    for topic, _, m in sink.messages:
        if topic == "/nmea/sentence":
            line += 1
        elif topic == "/wind/true" and m["source"] == "nmea":
            by_line[line] = m
    rows = list(csv.DictReader(open(REAL / "nmea" / "reference_true_wind.csv")))
    for r in rows:
        m = by_line[int(r["wind_line"])]
        assert abs(m["speed"] / KNOT - float(r["opencpn_tws_kn"])) < 0.1
        assert abs(wrap_to_180(m["dir"] - float(r["opencpn_twd_deg"]))) < 1.0
        assert m["heading"] == pytest.approx(float(r["hdt_deg"]))
