"""Field logs reach the samples table: real NMEA captures, set and drift, DataFlash, both wind routes.

Values are checked against rows computed by hand from the raw sentences (parsed here with plain
string splitting, not with forcemap's parser) and against ``reference_true_wind.csv``, which an
independent script derived from the same capture.
"""

from __future__ import annotations

import csv
import math
import struct
from pathlib import Path

import pytest
from forcemap.host.cli import main
from forcemap.host.convert.importers import import_file, import_nmea
from forcemap.host.fuse import compensation as comp
from forcemap.host.fuse.pipeline import ListSink, Pipeline
from forcemap.host.log.mcap import FileScan, iter_records, read_messages
from forcemap.host.vessel.geodesy import to_direction, velocity, wrap_to_180

from tests.tools import REAL, validate_log_schemas

KN = 1852.0 / 3600.0

PACCUP = REAL / "nmea" / "PacCupStartNMEA.txt"
REFERENCE = REAL / "nmea" / "reference_true_wind.csv"

# rows exported from PacCupStart, and the share of rows that are non-empty per column. 2203 until
# issue 20: now the position gap bridged is 1.6 times the receiver's own interval (2 s), not 2 s,
# so 4 rows at the start have a position.
PACCUP_ROWS = 2207
PACCUP_SHARE = dict.fromkeys(
    (
        "t lat lon heading yaw_rate sog cog depth water_temp wind_speed wind_dir wind_east "
        "wind_north app_wind_speed app_wind_angle current_speed current_dir current_east "
        "current_north stw current_speed_stw current_dir_stw"
    ).split(),
    1.0,
)
# issue 37: every row says whether the bottom was lost there (the Golden Gate channel: 266 soundings
# from 32.1 to 36.5 min), and each sounding where it was not has its TVU
PACCUP_LOST = 266
PACCUP_SHARE |= {"bottom_lost": 1.0, "depth_tvu": (PACCUP_ROWS - PACCUP_LOST) / PACCUP_ROWS}
# every row has a yaw rate: the smoothed heading's rate (docs/NAVIGATION.md) is defined from the
# first heading on; the live pipeline's slope needed two headings, so its first two rows had none


@pytest.fixture(scope="module")
def paccup(real_case):
    """`forcemap import` and `forcemap export` of the capture: the run's one (tests/real_cases.py)."""
    built = real_case("nmea/PacCupStartNMEA.txt")
    assert built.import_rc == 0, built.import_text
    with open(built.csv) as f:
        rows = list(csv.DictReader(f))
    return built.mcap, rows


def test_paccup_import_then_export_gives_samples(paccup):
    _, rows = paccup
    assert len(rows) == PACCUP_ROWS
    share = {c: sum(r[c] != "" for r in rows) / len(rows) for c in rows[0]}
    assert share == pytest.approx(PACCUP_SHARE, abs=0.0005)
    for c in ("wind_speed", "wind_dir", "depth", "current_speed", "current_dir"):
        assert share[c] >= 0.9
    # no wheels, no bridge, no instrument true wind in this capture: those columns are left out
    assert "wheel1_speed" not in rows[0] and "wind_speed_instrument" not in rows[0]


def test_every_logged_message_matches_the_schema_in_the_file(paccup):
    mcap, _ = paccup
    n, names = validate_log_schemas(mcap)
    assert n > 60000
    assert {"foxglove.LocationFix", "forcemap.Sample", "forcemap.SetAndDrift"} <= names


def test_the_columns_metadata_says_who_fed_each_column(paccup):
    mcap, _ = paccup
    scan = FileScan(mcap)
    list(iter_records(mcap, scan))
    cols = [dict(m.metadata) for m in scan.metadata if m.name == "columns"][-1]
    # a column's source: the connection, talker and sentence (forcemap.host.fuse.sources)
    assert cols["depth"] == "nmea IIDBT" and cols["water_temp"] == "nmea IIMTW"
    assert cols["stw"] == "nmea IIVHW" and cols["app_wind_speed"] == "nmea IIVWR"
    assert cols["heading"] == "nmea IIHDM +variation"
    assert "nmea IIVWR + nmea IIHDM +variation" in cols["wind_speed"]
    assert cols["current_speed"].startswith("nmea IIVHW + nmea IIHDM +variation")
    # one receiver (talker EC, whole seconds, 3-decimal minutes): its RMC, GGA and GLL alike
    assert {x.split(" ", 1)[1][:2] + x.rsplit("[", 1)[1] for x in cols["lat"].split("; ")} == {
        "EChhmmss 3dp]"
    }


def _fields(line: str) -> list[str]:
    return line.split("*")[0].split(",")


def _hand_set_and_drift(sog_kn, cog, heading, stw_kn):
    """Ground velocity minus STW along the heading, in knots and degrees TO (by hand)."""
    ge, gn = sog_kn * math.sin(math.radians(cog)), sog_kn * math.cos(math.radians(cog))
    we, wn = stw_kn * math.sin(math.radians(heading)), stw_kn * math.cos(math.radians(heading))
    e, n = ge - we, gn - wn
    return math.hypot(e, n), math.degrees(math.atan2(e, n)) % 360.0


def test_set_and_drift_matches_the_reference_rows():
    lines = PACCUP.read_text(errors="replace").splitlines()
    rows = list(csv.DictReader(open(REFERENCE)))
    assert len(rows) == 20
    for r in rows:
        rmc = _fields(lines[int(r["rmc_line"]) - 1])
        vhw = _fields(lines[int(r["vhw_line"]) - 1])
        hdm = _fields(lines[int(r["heading_line"]) - 1])
        assert rmc[0].endswith("RMC") and vhw[0].endswith("VHW") and hdm[0].endswith("HDM")
        sog, cog = float(rmc[7]), float(rmc[8])
        variation = float(rmc[10]) * (1 if rmc[11] == "E" else -1)
        heading = float(hdm[1]) + variation
        stw = float(vhw[5])
        drift, set_to = _hand_set_and_drift(sog, cog, heading, stw)
        assert drift == pytest.approx(float(r["current_drift_kn"]), abs=0.002)
        assert abs(wrap_to_180(set_to - float(r["current_set_toward_deg"]))) < 0.1
        e, n = comp.current_from_stw(stw * KN, heading, *velocity(sog * KN, cog))
        assert math.hypot(e, n) / KN == pytest.approx(float(r["current_drift_kn"]), abs=0.002)
        assert abs(wrap_to_180(to_direction(e, n) - float(r["current_set_toward_deg"]))) < 0.1


def test_samples_at_the_reference_rows_agree_with_the_hand_computation():
    """The rows are paced by VHW: the row at a reference row's VHW line carries that line's STW
    exactly; heading, ground velocity and the current come from interpolation between sentences,
    so they agree with the reference (nearest sentences) within what one sentence period moves."""
    sink = ListSink()
    res = import_nmea(PACCUP, sink)
    assert res.counters["samples"]["paced_by"] == "nmea IIVHW"
    line_ns, n = {}, 0
    for topic, ns, _ in sink.messages:
        if topic == "/nmea/sentence":
            n += 1
            line_ns[n] = ns
    samples = {round(s["t"] * 1e9): s for s in sink.topic("/samples")}
    lines = PACCUP.read_text(errors="replace").splitlines()
    checked = 0
    for r in csv.DictReader(open(REFERENCE)):
        s = samples.get(line_ns[int(r["vhw_line"])])
        if s is None:
            continue  # the first seconds: the capture's GPS time stands still, no position yet
        checked += 1
        assert s["stw"] / KN == pytest.approx(float(_fields(lines[int(r["vhw_line"]) - 1])[5]))
        dbt = [ln for ln in lines[: int(r["vhw_line"])] if ln.startswith("$IIDBT")][-1]
        nearest_depth = float(_fields(dbt)[3])
        assert abs(s["depth"] - nearest_depth) <= 1.0
        assert abs(wrap_to_180(s["heading"] - float(r["hdt_deg"]))) <= 2.0
        # the reference takes the RMC before the row, the sample interpolates to the next one: they
        # may differ by what the ground velocity changes in that period (0.3 kn at the start)
        rmc_at = int(r["rmc_line"])
        nxt = next(ln for ln in lines[rmc_at:] if ln.startswith("$ECRMC"))
        v0, v1 = (
            velocity(float(f[7]), float(f[8])) for f in map(_fields, (lines[rmc_at - 1], nxt))
        )
        dv = math.hypot(v1[0] - v0[0], v1[1] - v0[1])
        drift = float(r["current_drift_kn"])
        assert s["current_speed_stw"] / KN == pytest.approx(drift, abs=0.15 + dv)
        # the apparent wind is the VWR sentence nearest in time: one of those around the row
        vwr = {
            (-float(f[1]) if f[2] == "L" else float(f[1]), float(f[3]))
            for ln in lines[int(r["vhw_line"]) - 60 : int(r["vhw_line"]) + 60]
            if ln.startswith("$IIVWR") and (f := _fields(ln))
        }
        assert (s["app_wind_angle"], round(s["app_wind_speed"] / KN, 6)) in {
            (a, round(v, 6)) for a, v in vwr
        }
        # true wind over ground by hand: W = R + V, R pointing away from where the wind comes from
        a = math.radians(s["heading"] + s["app_wind_angle"])
        e = -s["app_wind_speed"] * math.sin(a) + s["sog"] * math.sin(math.radians(s["cog"]))
        n = -s["app_wind_speed"] * math.cos(a) + s["sog"] * math.cos(math.radians(s["cog"]))
        assert s["wind_speed"] == pytest.approx(math.hypot(e, n), rel=1e-9)
        assert s["wind_dir"] == pytest.approx(math.degrees(math.atan2(-e, -n)) % 360.0)
        assert abs(wrap_to_180(s["wind_dir"] - float(r["sk_ground_gwd_deg"]))) <= 6.0
    # 12 until issue 20: the first 6 s had no position; the receiver's own gap (3.2 s) gives them one
    assert checked == 16


# --- DataFlash ----------------------------------------------------------------------------------------

HEAD = b"\xa3\x95"
FMT_ID = 128


def _fmt(type_id: int, name: str, fmt: str, columns: str) -> bytes:
    length = 3 + struct.calcsize("<" + _structs(fmt))
    body = struct.pack(
        "<BB4s16s64s", type_id, length, name.encode(), fmt.encode(), columns.encode()
    )
    return HEAD + bytes([FMT_ID]) + body


def _structs(fmt: str) -> str:
    table = {"Q": "Q", "B": "B", "I": "I", "H": "H", "L": "i", "e": "i", "f": "f", "h": "h"}
    table |= {"C": "H", "c": "h", "b": "b", "n": "4s", "N": "16s", "Z": "64s", "d": "d"}
    return "".join(table[c] for c in fmt)


def _rec(type_id: int, fmt: str, *values) -> bytes:
    return HEAD + bytes([type_id]) + struct.pack("<" + _structs(fmt), *values)


def write_dataflash(path: Path, seconds: int = 30) -> list[tuple[float, float, float, float]]:
    """A small .BIN in the documented format: FMT records, then FMTU/MULT, then GPS, ATT, RFND at
    5 Hz. RFND's distance is an int16 in centimetres with an FMTU multiplier of 0.01.
    Returns (t since start, lat, heading, depth) per GPS record."""
    gps_f, att_f, rfnd_f = "QBIHBcLLeffB", "QccC", "QBhB"
    out = bytearray()
    out += _fmt(FMT_ID, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")
    out += _fmt(179, "MULT", "Qbd", "TimeUS,Id,Mult")
    out += _fmt(177, "FMTU", "QBNN", "TimeUS,FmtType,UnitIds,MultIds")
    out += _fmt(130, "GPS", gps_f, "TimeUS,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs,U")
    out += _fmt(131, "ATT", att_f, "TimeUS,Roll,Pitch,Yaw")
    out += _fmt(132, "RFND", rfnd_f, "TimeUS,Instance,Dist,Orient")
    out += _rec(179, "Qbd", 0, ord("B"), 0.01)
    out += _rec(177, "QBNN", 0, 132, b"s#m-", b"F-B-")
    truth = []
    week, ms0 = 2300, 100_000_000
    for k in range(seconds * 5):
        t = k * 0.2
        us = 10_000_000 + int(t * 1e6)
        lat, lon = 47.0 + 1e-5 * t, 8.0 + 2e-5 * t
        heading = (30.0 + 2.0 * t) % 360.0
        depth = 3.0 + 0.05 * t
        gps = (us, 3, ms0 + int(t * 1000), week, 12, 90)
        gps += (int(round(lat * 1e7)), int(round(lon * 1e7)), 40000, 1.5, 45.0, 1)
        out += _rec(130, gps_f, *gps)
        out += _rec(131, att_f, us + 1000, 0, 0, int(round(heading * 100)))
        out += _rec(132, rfnd_f, us + 2000, 0, int(round(depth * 100)), 25)
        truth.append((t, lat, heading, depth))
    path.write_bytes(bytes(out))
    return truth


def test_a_dataflash_log_with_gps_att_and_rfnd_gives_samples(tmp_path, capsys):
    path = tmp_path / "boat.BIN"
    truth = write_dataflash(path)
    sink = ListSink()
    res = import_file(path, sink)
    assert res.format == "dataflash" and res.records == 3 + 3 + 2 + 3 * len(truth)
    rows = sink.topic("/samples")
    assert len(rows) == len(truth)  # paced by RFND, one row per sounding
    assert all(r["depth"] is not None and r["lat"] is not None for r in rows)
    assert all(r["heading"] is not None and r["sog"] is not None for r in rows[1:-1])
    # by hand: RFND 350 cm at t = 2.5 s is 3.125 m; the heading then is 30 + 2 * 2.5 deg
    mid = rows[len(rows) // 2]
    t_mid = truth[len(rows) // 2][0]
    assert mid["depth"] == pytest.approx(3.0 + 0.05 * t_mid, abs=0.01)
    assert mid["heading"] == pytest.approx(30.0 + 2.0 * t_mid, abs=0.05)
    assert mid["sog"] == pytest.approx(1.5, abs=1e-6) and mid["cog"] == pytest.approx(45.0)
    cols = [m for n, m in sink.meta if n == "columns"][-1]
    assert cols["depth"] == "dataflash RFND" and cols["lat"] == "dataflash GPS"
    # the whole command: an MCAP that exports the same rows
    out = tmp_path / "out"
    out.mkdir()
    assert main(["import", str(path), "-o", str(out)]) == 0
    (mcap,) = out.glob("*.mcap")
    assert sum(1 for _ in read_messages(mcap, "/samples")) == len(truth)
    capsys.readouterr()


def test_no_position_no_time_no_measurements_are_one_line_and_no_file(tmp_path, capsys):
    cases = {
        "nopos.nmea": "$IIMTW,016,C*3A\n" * 20,
        "notime.nmea": "$IIHDM,303,M*3C\n$IIVHW,,T,303,M,06.99,N,12.61,K*67\n" * 10,
    }
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "o").mkdir()
    assert main(["import", str(tmp_path / "notime.nmea"), "-o", str(tmp_path / "o")]) == 2
    assert "no time in this log" in capsys.readouterr().err
    zda = "$ECZDA,194310,14,07,2008,,*5F\n"
    (tmp_path / "nopos.nmea").write_text(zda + "$IIMTW,016,C*3A\n" * 20)
    assert main(["import", str(tmp_path / "nopos.nmea"), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no position in this log" in err
    nomeas = tmp_path / "nomeas.nmea"
    rmc = "$ECRMC,194310,A,3748.784,N,12226.831,W,8.0,316.0,140708,015.0,E,A*18\n"
    nomeas.write_text(zda + rmc * 5)
    assert main(["import", str(nomeas), "-o", str(tmp_path / "o")]) == 2
    assert "no measurements in this log" in capsys.readouterr().err
    assert not list((tmp_path / "o").iterdir())


def _nmea(body: str) -> bytes:
    x = 0
    for ch in body.encode():
        x ^= ch
    return f"${body}*{x:02X}\r\n".encode()


def test_paddle_wheels_and_a_speed_log_are_both_logged():
    """A bridge boat that also has a VHW log: the wheels give `current_*`, the log set and drift."""
    from bench.synth_streams import generate

    events, _ = generate(60, seed=5)
    vhw = _nmea("IIVHW,,T,,M,2.92,N,5.40,K")
    extra = [("nmea", mono, wall, vhw) for src, mono, wall, _ in events if src == "depth"]
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    for e in sorted(events + extra, key=lambda e: e[2]):
        pipe.feed(*e)
    pipe.close()
    rows = sink.topic("/samples")
    assert len(rows) == 60 * 4
    both = [
        r for r in rows if r["current_speed"] is not None and r["current_speed_stw"] is not None
    ]
    assert len(both) >= 0.9 * len(rows)
    assert all(r["stw"] == pytest.approx(2.92 * KN) for r in both)
    cols = [m for n, m in sink.meta if n == "columns"][-1]
    assert cols["current_speed"].startswith("bridge paddle wheels")
    assert cols["current_speed_stw"].split(" ")[1] == "IIVHW", cols["current_speed_stw"]
    assert len(sink.topic("/current")) == len(rows) and len(sink.topic("/current/stw")) == len(both)


def test_a_fixed_sample_rate_gives_a_grid():
    """With ``sample_rate_hz`` the rows fall on a fixed grid instead of the fastest stream's readings."""
    from forcemap.host.convert.importers import nmea_line_times
    from forcemap.host.decode.nmea import LineSplitter

    path = REAL / "nmea" / "bundg_zeus_9.log"
    splitter = LineSplitter()
    lines = splitter.feed(path.read_bytes()) + splitter.flush()
    times, _ = nmea_line_times(lines)
    sink = ListSink()
    pipe = Pipeline(sink=sink, sample_rate_hz=0.5)
    for line, t in zip(lines, times, strict=True):
        pipe.feed("nmea", int(t * 1e9), int(t * 1e9), line + b"\n")
    pipe.close()
    ts = [r["t"] for r in sink.topic("/samples")]
    assert all(t % 2.0 == pytest.approx(0.0, abs=1e-6) for t in ts)
    assert all(b - a == pytest.approx(2.0, abs=1e-6) for a, b in zip(ts, ts[1:], strict=False))
    assert abs(len(ts) - (times[-1] - times[0]) / 2.0) <= 3
