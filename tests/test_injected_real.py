"""Real logs with a known effect put into their NMEA sentences (bench/inject_nmea.py, issue 36).

First the injector alone, against the raw lines read here with plain string splitting: injecting
nothing gives every real log back byte for byte; only the sentences and fields an effect touches
change; positions move by the truth's displacement, the ground velocity gains the truth's current,
the wind over ground computed by hand from the apparent wind stays the recorded one, and soundings
read deeper by the level; a bus's checksum variant is kept; outputs never overwrite the input.

Then through the pipeline (each case imported and exported once per run, tests/real_cases.py):
2-minute means of the table's current and depth recover the truth's, as the difference from the
clean log's table at the same rows and, for the current, alone (the real log's own current is the
noise); the pipeline's physical checks still hold; heading, STW and the wind over ground do not
carry the injected current. Diagnose's verdicts on these cases are the lead's (issue 36).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from forcemap.host.convert.capture_file import capture_bytes
from forcemap.host.decode.nmea_checksum import variant_of, xor
from forcemap.host.fuse.declination import igrf_declination
from forcemap.host.vessel.geodesy import LocalFrame, boat_to_world, velocity

from bench.inject_cases import FJORD, GENEVA_2008, INJECTED
from bench.inject_effects import Current, Effect, Shape
from bench.inject_nmea import inject, main, read_truth
from bench.inject_verify import bin_means, read_table, recovery, truth_at
from tests.tools import real_data

REAL = real_data()
KN = 1852.0 / 3600.0
NMEA_LOGS = sorted(
    p.relative_to(REAL).as_posix()
    for p in (REAL / "nmea").rglob("*")
    if p.is_file() and p.suffix not in (".md", ".csv")
)
CHECKSUMS = "nmea/irene/irene_2013-07-31_flensburg_checksums.nmea"
# the fields (after the address) each effect may change
CURRENT_FIELDS = {
    "RMC": {2, 3, 4, 5, 6, 7},
    "GLL": {0, 1, 2, 3},
    "GGA": {1, 2, 3, 4},
    "VTG": {0, 2, 4, 6},
    "MWV": {0, 2},
    "VWR": {0, 1, 2, 4, 6},
}
LEVEL_FIELDS = {"DPT": {0}, "DBT": {0, 2, 4}}


def _lines(path) -> list[str]:
    return capture_bytes(path).decode("latin-1").split("\n")


def _fields(line: str) -> tuple[str, list[str], str]:
    """(sentence type, fields after the address, checksum) by plain splitting."""
    body, _, cs = line.strip().lstrip("$").partition("*")
    f = body.split(",")
    return f[0][-3:], f[1:], cs[:2]


def _deg(v: str, h: str) -> float:
    x = float(v)
    d = math.floor(x / 100)
    return (d + (x - 100 * d) / 60) * (-1 if h in "SW" else 1)


def _rmc_time(f: list[str]) -> float:
    import calendar

    d, m, y = int(f[8][:2]), int(f[8][2:4]), 2000 + int(f[8][4:])
    return (
        calendar.timegm((y, m, d, 0, 0, 0))
        + int(f[0][:2]) * 3600
        + int(f[0][2:4]) * 60
        + int(f[0][4:6])
    )


@pytest.fixture(scope="module")
def fjord_tide(tmp_path_factory):
    """The fjord_tide case's capture and truth, injected here (no import: 1.5 s)."""
    out = tmp_path_factory.mktemp("inject") / "fjord_tide.nmea"
    inject(REAL / FJORD, out, INJECTED["fjord_tide"].effect)
    return _lines(REAL / FJORD), _lines(out), read_truth(out.with_name("fjord_tide.truth.csv"))


# a log the injector does not give back yet, and what it does: a known miss, strict, so a fix shows
NOT_YET = {
    "nmea/sfbay/duxbury.nmea.gz": "one field comes back rewritten at null effect (byte 11,675,009 of the "
    "capture): the second San Francisco Bay day, shipped this stop, not yet examined",
}


@pytest.mark.parametrize(
    "log",
    [pytest.param(n, marks=pytest.mark.xfail(reason=NOT_YET[n], strict=True)) if n in NOT_YET else n
     for n in NMEA_LOGS],
)  # fmt: skip
def test_injecting_nothing_gives_the_log_back_byte_for_byte(log, tmp_path):
    """Every sentence an effect would touch goes through the rewriting, with effects of size 0:
    each rewritten field comes back as the log wrote it (decimals, padding, sign, checksum case)."""
    null = Effect(Current(Shape("tidal", 0.0), 50.0), Shape("tidal", 0.0))
    out = tmp_path / ("out.nmea.gz" if log.endswith(".gz") else "out.nmea")
    rep, _ = inject(REAL / log, out, null)
    assert capture_bytes(out) == capture_bytes(REAL / log)
    assert rep.lines == capture_bytes(REAL / log).count(b"\n") + 1 and not rep.changed


@pytest.mark.parametrize("name", ["fjord_tide", "fjord_level"])
def test_only_the_effects_sentences_and_fields_change(name, tmp_path):
    out = tmp_path / "out.nmea"
    rep, _ = inject(REAL / FJORD, out, INJECTED[name].effect)
    allowed = CURRENT_FIELDS if name == "fjord_tide" else LEVEL_FIELDS
    a, b = _lines(REAL / FJORD), _lines(out)
    assert len(a) == len(b)
    changed = {}
    for x, y in zip(a, b, strict=True):
        if x == y:
            continue
        (ta, fa, _), (tb, fb, cb) = _fields(x), _fields(y)
        assert ta == tb and len(fa) == len(fb) and x.endswith("\r") == y.endswith("\r")
        assert {i for i, (u, v) in enumerate(zip(fa, fb, strict=True)) if u != v} <= allowed[ta]
        assert [len(u.partition(".")[2]) for u in fa] == [len(v.partition(".")[2]) for v in fb]
        body = y.strip().lstrip("$").partition("*")[0]
        assert int(cb, 16) == xor(body)  # the log's checksums are correct, and stay so
        changed[ta] = changed.get(ta, 0) + 1
    assert changed == dict(rep.changed) and set(changed) <= set(allowed)
    assert sum(changed.values()) > 0.5 * sum(_fields(x)[0] in allowed for x in a)


def test_positions_move_by_the_truths_displacement(fjord_tide):
    """Per fix, the moved position minus the recorded one is the truth's displacement at the fix's
    own stamp, within the log's resolution (0.001 minute: 1.85 m north, 1.07 m east); the rounding
    errors are carried from fix to fix, so they do not add up to a bias."""
    a, b, truth = fjord_tide
    first = next(_fields(x)[1] for x in a if _fields(x)[0] == "GLL" and _fields(x)[1][0])
    frame = LocalFrame(_deg(first[0], first[1]), _deg(first[2], first[3]))  # the log's start
    err = []
    for x, y in zip(a, b, strict=True):
        (t, fa, _), (_, fb, _) = _fields(x), _fields(y)
        if t != "RMC" or not fa[2] or len(fa) < 9 or not fa[8]:
            continue
        x0, y0 = frame.to_local(_deg(fa[2], fa[3]), _deg(fa[4], fa[5]))
        x1, y1 = frame.to_local(_deg(fb[2], fb[3]), _deg(fb[4], fb[5]))
        ts = _rmc_time(fa)
        err.append(
            (
                x1 - x0 - truth_at(truth, "offset_east", ts),
                y1 - y0 - truth_at(truth, "offset_north", ts),
            )
        )
    err = np.array(err)
    assert len(err) > 10000 and np.isfinite(err).all()
    assert np.abs(err[:, 0]).max() < 1.07 * 1.01 and np.abs(err[:, 1]).max() < 1.85 * 1.01
    assert np.abs(err.mean(axis=0)).max() < 0.05
    assert np.ptp(truth["offset_east"]) > 500  # the effect moved the track by far more than that


def test_ground_velocity_gains_the_truths_current(fjord_tide):
    """RMC's speed and course: new minus recorded is the truth's current at the fix, within what
    one decimal of a knot and a whole degree can say, and without a bias."""
    a, b, truth = fjord_tide
    got, want, bound = [], [], []
    for x, y in zip(a, b, strict=True):
        (t, fa, _), (_, fb, _) = _fields(x), _fields(y)
        if t != "RMC" or not fa[6] or not fa[7] or not fa[8]:
            continue
        v0 = velocity(float(fa[6]) * KN, float(fa[7]))
        v1 = velocity(float(fb[6]) * KN, float(fb[7]))
        ts = _rmc_time(fa)
        got.append((v1[0] - v0[0], v1[1] - v0[1]))
        want.append((truth_at(truth, "current_east", ts), truth_at(truth, "current_north", ts)))
        # the new one's rounding, its error carried from the last: up to one unit of each field
        bound.append(0.1 * KN + float(fb[6]) * KN * math.radians(1.0))
    got, want = np.array(got), np.array(want)
    miss = np.hypot(*(got - want).T)
    assert len(miss) > 10000 and (miss <= np.array(bound) * 1.01 + 1e-6).all()
    assert np.abs(np.mean(got - want, axis=0)).max() < 0.005


def test_the_wind_over_ground_stays_the_recorded_one(fjord_tide):
    """By hand, W = R + V from each VWR (turned by the last HDG and IGRF's declination) and the last
    RMC's velocity: the injected log's W is the recorded log's, sentence by sentence, within the
    resolution of the apparent wind (0.1 kn, 1 deg), and carries none of the current."""
    a, b, truth = fjord_tide
    decl = igrf_declination(
        54.85, 9.54, _rmc_time(_fields(next(x for x in a if "RMC," in x and ",A," in x))[1])
    )

    def winds(lines):
        out, hdg, v, ts = [], None, None, None
        for line in lines:
            t, f, _ = _fields(line)
            if t == "HDG" and f[0]:
                hdg = float(f[0]) + decl
            elif t == "RMC" and f[6] and f[7] and f[8]:
                v, ts = velocity(float(f[6]) * KN, float(f[7])), _rmc_time(f)
            elif t == "VWR" and f[0] and f[2] and hdg is not None and v is not None:
                ang = math.radians(float(f[0]) * (-1 if f[1] == "L" else 1))
                s = float(f[2]) * KN
                re, rn = boat_to_world(-s * math.cos(ang), -s * math.sin(ang), hdg)
                out.append((ts, re + v[0], rn + v[1], s))
        return np.array(out)

    w0, w1 = winds(a), winds(b)
    assert w0.shape == w1.shape and len(w0) > 10000
    d = w1[:, 1:3] - w0[:, 1:3]
    res = 0.05 * KN + np.maximum(w0[:, 3], w1[:, 3]) * math.radians(0.5)
    # two roundings of the apparent wind, and the ground velocity's, at most
    assert np.percentile(np.hypot(*d.T) / (2 * res + 0.05 * KN + 0.035), 99) < 1.0
    # what is left does not follow the current (an apparent wind left as recorded: slope +1)
    for k, col in enumerate(("current_east", "current_north")):
        x = truth_at(truth, col, w0[:, 0])
        assert np.std(x) > 0.05
        x = x - x.mean()
        assert abs(np.dot(x, d[:, k] - d[:, k].mean()) / np.dot(x, x)) < 0.05


def test_soundings_read_deeper_by_the_level(tmp_path):
    out = tmp_path / "level.nmea"
    inject(REAL / FJORD, out, INJECTED["fjord_level"].effect)
    truth = read_truth(tmp_path / "level.truth.csv")
    ts, d = None, []
    for x, y in zip(_lines(REAL / FJORD), _lines(out), strict=True):
        t, fa, _ = _fields(x)
        if t == "RMC" and fa[0] and fa[8]:
            ts = _rmc_time(fa)
        elif t == "DPT" and fa[0] and ts is not None:
            d.append((ts, float(_fields(y)[1][0]) - float(fa[0])))
    d = np.array(d)
    miss = d[:, 1] - truth_at(truth, "level", d[:, 0])
    assert len(d) > 10000 and np.abs(miss).max() < 0.1 + 0.6 / 3600  # 0.1 m readings, 1 s of stamp
    assert abs(miss.mean()) < 0.005 and np.ptp(d[:, 1]) == pytest.approx(0.6, abs=0.1)


def test_a_bus_checksum_variant_is_kept(tmp_path):
    """Irene 2013-07-31's bus checksums over the address only: each rewritten sentence keeps the
    convention its line had, so forcemap's lenient reading accepts exactly as many lines."""
    from forcemap.host.decode.nmea import NmeaParser

    out = tmp_path / "c.nmea"
    rep, _ = inject(REAL / CHECKSUMS, out, INJECTED["fjord_tide"].effect)
    assert sum(rep.changed.values()) > 10000
    a, b = _lines(REAL / CHECKSUMS), _lines(out)
    kept = 0
    for x, y in zip(a, b, strict=True):
        if x != y and "*" in x:
            bx, _, cx = x.strip().lstrip("$").partition("*")
            by, _, cy = y.strip().lstrip("$").partition("*")
            conv = "std" if xor(bx) == int(cx[:2], 16) else variant_of(bx, int(cx[:2], 16))
            assert conv, x  # a line whose checksum matches nothing is never rewritten
            if conv == "std":
                assert xor(by) == int(cy[:2], 16), y
            else:  # the same variant: over the address only, whatever the fields say
                assert xor(by.split(",")[0]) == int(cy[:2], 16) and cy == cx, (x, y)
                kept += 1
    assert kept > 10000

    def accepted(lines):
        p = NmeaParser("lenient")
        return sum(1 for ln in lines if (s := p.parse(ln.strip())) is not None and s.valid)

    assert accepted(b) == accepted(a)


def test_gzip_in_and_out_as_plain(tmp_path):
    import gzip

    src = REAL / "nmea" / "bundg_zeus_9.log"
    gz = tmp_path / "b.log.gz"
    gz.write_bytes(gzip.compress(src.read_bytes()))
    eff = INJECTED["fjord_tide"].effect
    inject(src, tmp_path / "plain.nmea", eff)
    inject(gz, tmp_path / "z.nmea.gz", eff)
    assert (
        gzip.decompress((tmp_path / "z.nmea.gz").read_bytes())
        == (tmp_path / "plain.nmea").read_bytes()
    )
    assert (tmp_path / "z.truth.csv").read_bytes() == (tmp_path / "plain.truth.csv").read_bytes()


def test_the_command_never_overwrites_its_input_and_says_why_in_one_line(tmp_path, capsys):
    src = tmp_path / "race.nmea"
    src.write_bytes((REAL / GENEVA_2008).read_bytes())
    before = src.read_bytes()
    cur = ["--current", "ramp amplitude=0.1 toward=90"]
    cases = [
        ([str(src), "-o", str(src), *cur], "also an input"),
        ([str(src), "-o", str(src), "--force", *cur], "also an input"),
        ([str(src), "-o", str(tmp_path / "o.nmea")], "--current SPEC"),
        ([str(src), "-o", str(tmp_path / "o.nmea"), "--current", "ramp toward=9"], "amplitude"),
        ([str(src), "-o", str(tmp_path / "o.nmea"), "--current", "ramp amplitude=1"], "toward"),
        (
            [str(src), "-o", str(tmp_path / "o.nmea"), "--level", "wave amplitude=1"],
            "unknown shape",
        ),
        ([str(tmp_path / "none.nmea"), "-o", str(tmp_path / "o.nmea"), *cur], "cannot read"),
        ([str(src), "-o", str(tmp_path / "o.nmea"), "--truth", str(src), *cur], "also an input"),
    ]
    for argv, says in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and says in err, (argv, err)
    assert src.read_bytes() == before and not (tmp_path / "o.nmea").exists()
    assert main([str(src), "-o", str(tmp_path / "o.nmea"), *cur]) == 0
    assert main([str(src), "-o", str(tmp_path / "o.nmea"), *cur]) == 2  # exists: --force
    assert "--force" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0 and "toward=DEG" in capsys.readouterr().out


# --- through the pipeline: import, calibration, the smoother, export ---------------------------


def _tables(real_case, name):
    built = real_case(name)
    clean = real_case(built.case.clean)
    assert built.import_rc == 0 and clean.import_rc == 0, built.import_text
    return built, clean, read_table(built.csv), read_table(clean.csv), read_truth(built.truth)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(INJECTED))
def test_the_pipeline_recovers_the_injected_part(name, real_case):
    """Issue 36: slope 0.9-1.1 on 2-minute means. As the difference from the clean table, the
    along-axis current and the depth within 0.95-1.05 (the self-calibration absorbs a few per cent
    of a seiche into the speed log's gain, bench/RESULTS.md); alone, the real log's own current is
    the noise, so its slope is judged by its own standard error (from the bins' own correlation)."""
    built, _, table, clean, truth = _tables(real_case, name)
    fits = recovery(table, truth, clean, built.case.toward_deg)
    diff = {f.quantity: f for f in fits if f.how == "difference"}
    alone = {f.quantity: f for f in fits if f.how == "alone"}
    assert diff, fits
    for q, f in diff.items():
        tight = q in ("current_along", "depth")
        lo, hi = (0.95, 1.05) if tight else (0.9, 1.1)
        assert lo <= f.slope <= hi and f.r > 0.95 and f.bins >= 40, f.line()
        assert abs(f.intercept) < 0.1 * f.truth_sd + 0.01, f.line()
    if "current_along" in alone:
        f = alone["current_along"]
        assert abs(f.slope - 1.0) < 3 * f.slope_se and f.slope > 3 * f.slope_se, f.line()


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(INJECTED))
def test_the_pipelines_physical_checks_hold_on_every_injected_case(name, real_case):
    built, clean, table, clean_table, _ = _tables(real_case, name)
    rep = built.check()
    found = {(c, f["check"]): f for c, v in rep["categories"].items() for f in v["findings"]}
    # the displacement over 30 s is the integrated ground velocity, within 2 % (test_qa_real)
    assert abs(found[("position", "vs_sog")]["value"] - 1) < 0.02
    if "heading" in clean_table:
        assert 0.5 < found[("rate_of_turn", "unit")]["value"] < 2.0
    else:  # a log without a heading (plaka) has no turn rate to check against it
        assert ("rate_of_turn", "unit") not in found
    assert np.array_equal(table["t"], clean_table["t"])  # no row lost or moved


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(INJECTED))
def test_heading_stw_and_the_wind_over_ground_do_not_carry_the_injected_current(name, real_case):
    """Row by row against the clean import: each quantity's typical change (the median) is within
    its own short-term noise (the RMS change from one row to the next in the clean table, over
    sqrt 2), and its 2-minute means do not follow the injected current (a slope under 0.1 of it)."""
    built, _, table, clean, truth = _tables(real_case, name)
    c = built.case.effect.current
    along = None
    if c is not None:
        ue, un = math.sin(math.radians(c.toward_deg)), math.cos(math.radians(c.toward_deg))
        along = (
            truth_at(truth, "current_east", table["t"]) * ue
            + truth_at(truth, "current_north", table["t"]) * un
        )
    cols = [c for c in ("heading", "stw", "wind_east", "wind_north") if c in clean]
    assert "stw" in cols and all(c in table for c in cols), cols  # plaka logs no heading, so no wind
    for col in cols:
        d = table[col] - clean[col]
        if col == "heading":
            d = (d + 180.0) % 360.0 - 180.0
        step = np.diff(clean[col])
        if col == "heading":
            step = (step + 180.0) % 360.0 - 180.0
        noise = np.sqrt(np.nanmean(step**2) / 2)  # one row's own scatter about its neighbours
        assert np.nanmedian(np.abs(d)) <= noise, (col, np.nanmedian(np.abs(d)), noise)
        if along is not None and col != "heading":
            y, x = bin_means(table["t"], truth["t"][0], d, along)
            slope = np.dot(x - x.mean(), y - y.mean()) / np.dot(x - x.mean(), x - x.mean())
            assert abs(slope) < 0.1, (col, slope)


def test_verify_measures_what_a_table_kept(tmp_path, capsys):
    """A table that kept 80 % of a known current over a clean one of correlated noise: the
    difference gives 0.8 exactly, the table alone 0.8 within its standard error (CSV, Parquet)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from bench.inject_nmea import write_truth
    from bench.inject_verify import BIN_S

    eff = Effect(Current(Shape("periodic", 0.2, period_s=3000.0), 30.0)).resolved(7200.0)
    write_truth(tmp_path / "t.csv", eff, 1.6e9, 1.6e9 + 7200.0)
    truth = read_truth(tmp_path / "t.csv")
    t = 1.6e9 + np.arange(0.0, 7200.0, 1.0)
    rng = np.random.default_rng(0)
    noise = np.cumsum(rng.normal(0, 0.01, (len(t), 2)), axis=0)  # a wandering real current
    clean = {"t": t, "current_east": noise[:, 0], "current_north": noise[:, 1]}
    kept = {
        "t": t,
        "current_east": noise[:, 0] + 0.8 * truth_at(truth, "current_east", t),
        "current_north": noise[:, 1] + 0.8 * truth_at(truth, "current_north", t),
    }
    fits = {(f.quantity, f.how): f for f in recovery(kept, truth, clean, 30.0)}
    assert fits["current_along", "difference"].slope == pytest.approx(0.8, abs=1e-9)
    alone = fits["current_along", "alone"]
    assert abs(alone.slope - 0.8) < 3 * alone.slope_se and alone.bins == 7200 / BIN_S
    pq.write_table(pa.table(kept), tmp_path / "kept.parquet")
    with open(tmp_path / "clean.csv", "w") as f:
        f.write("t,current_east,current_north\n")
        for row in zip(*clean.values(), strict=True):
            f.write(",".join(f"{v:.9f}" for v in row) + "\n")
    argv = ["--verify", str(tmp_path / "kept.parquet"), "--truth", str(tmp_path / "t.csv")]
    assert main([*argv, "--clean", str(tmp_path / "clean.csv"), "--toward", "30"]) == 0
    out = capsys.readouterr().out
    line = next(
        ln for ln in out.splitlines() if ln.startswith("current_along") and "difference" in ln
    )
    assert "slope  0.800" in line, out
    assert main(["--verify", str(tmp_path / "kept.parquet")]) == 2  # no truth: one line
    assert capsys.readouterr().err.count("\n") == 1
