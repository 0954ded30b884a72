"""Moving-boat ADCP files as surveys (issue 32): the three real TRDI files against dolfyn's own
readings (.nc), referenced velocities by hand, the compass offset against an independent scan, the
file without bottom-track lock or GPS, QA findings in the log, and the import's command line."""

from __future__ import annotations

import csv
import math
import sys

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.extras import install_hint
from forcemap.host.log.mcap import iter_records, read_messages
from forcemap.host.log.qa_records import QaFinding, is_finding

from tests.tools import IN_CI, real_data, validate_log_schemas

try:
    import mhkit  # noqa: F401
    import xarray as xr
except ImportError:
    if IN_CI:
        raise
    pytest.skip('needs pip install ".[adcp]"', allow_module_level=True)

from forcemap.host.convert.adcp import process  # noqa: E402
from forcemap.host.convert.adcp_nav import rotate  # noqa: E402
from forcemap.host.convert.adcp_read import count_ensembles, is_pd0, read_pd0  # noqa: E402

FILES = ["winriver01.PD0", "RiverPro_test01.PD0", "RDI_withBT.000"]


def _dir():
    return real_data() / "adcp"


@pytest.fixture(scope="module")
def raws():
    return {name: read_pd0(_dir() / name) for name in FILES}


def _secs(values) -> np.ndarray:
    return np.asarray(values).astype("datetime64[ns]").astype(np.int64) / 1e9


def test_every_file_in_the_adcp_folder_is_read(raws):
    data = sorted(p.name for p in _dir().iterdir() if p.suffix.lower() not in (".nc", ".md"))
    assert data == sorted(FILES)
    for name in data:
        assert is_pd0((_dir() / name).read_bytes()[:4096])
        assert (_dir() / name).with_suffix(".nc").is_file()
        assert raws[name].n > 0


@pytest.mark.parametrize("name", FILES)
def test_agrees_with_dolfyns_own_reading(raws, name):
    """Counts, times, positions, depth and the velocities before referencing, to float precision.

    dolfyn's regression reading of RDI_withBT.000 was made with ``nens=100`` (its test_read_adp.py);
    the other two are whole files. dolfyn leaves out a file's last ensemble (nothing follows it), so
    the checksum count from the bytes is one more for a complete file. winriver01.nc was read with a
    declination of 8.28 deg from a userdata file we do not have: its headings are ours + 8.28.
    """
    raw = raws[name]
    nc = xr.open_dataset(_dir() / name.replace(name.split(".")[-1], "nc"))
    k = nc.sizes["time"]
    if name == "RDI_withBT.000":
        assert k == 100 and raw.n == count_ensembles(_dir() / name)  # truncated: no whole last one
        raw = raw.head(k)
    else:
        assert raw.n == k == count_ensembles(_dir() / name) - 1
    assert np.array_equal(raw.number, nc["number"].values)
    np.testing.assert_allclose(raw.t_inst, _secs(nc["time"].values), rtol=0, atol=1e-6)
    np.testing.assert_array_equal(raw.vel_raw, nc["vel"].values)
    np.testing.assert_array_equal(raw.vel_bt_raw, nc["vel_bt"].values)
    np.testing.assert_array_equal(np.nan_to_num(raw.dist_bt), nc["dist_bt"].values[:4])
    np.testing.assert_array_equal(raw.draft, nc["depth"].values)
    decl = float(nc.attrs.get("declination", 0.0))
    np.testing.assert_allclose(np.mod(raw.heading + decl, 360), nc["heading"].values, atol=2e-5)
    for ours, theirs in (("pitch", "pitch"), ("roll", "roll"), ("temp", "temp")):
        np.testing.assert_array_equal(getattr(raw, ours), nc[theirs].values)
    if "latitude_gps" in nc:
        np.testing.assert_array_equal(raw.lat, nc["latitude_gps"].values)
        np.testing.assert_array_equal(raw.lon, nc["longitude_gps"].values)
        np.testing.assert_allclose(raw.t_gps, _secs(nc["time_gps"].values), rtol=0, atol=1e-6)
    else:
        assert not raw.has_gps


def test_referenced_velocities_by_hand(raws, tmp_path):
    """winriver01 records in the ship frame (x starboard, y forward; tilts already applied), so by
    hand: east = x cos h + y sin h, north = -x sin h + y cos h with h = heading + the compass offset;
    water over ground referenced to bottom track = that rotation of (water - bottom), since the
    bottom track is the bed's velocity relative to the boat. Checked on five ensembles' first valid
    cells against the MCAP's /adcp/profile, and the GPS-referenced one against water + GPS velocity.
    """
    path = _dir() / "winriver01.PD0"
    out = tmp_path / "w.mcap"
    assert main(["import", str(path), "-o", str(out)]) == 0
    survey = process(raws["winriver01.PD0"])
    delta = survey.offset_applied
    profiles = [m.message for m in read_messages(out, "/adcp/profile")]
    nc = xr.open_dataset(_dir() / "winriver01.nc")
    x, y = nc["vel"].values[0], nc["vel"].values[1]
    bx, by = nc["vel_bt"].values[0], nc["vel_bt"].values[1]
    checked = 0
    for i in (10, 60, 120, 180, 240):
        p = profiles[i]
        k = next(j for j, v in enumerate(p["east"]) if v is not None)
        h = math.radians(float(nc["heading"].values[i]) - nc.attrs["declination"] + delta)
        wx, wy = x[k, i] - bx[i], y[k, i] - by[i]
        east = wx * math.cos(h) + wy * math.sin(h)
        north = -wx * math.sin(h) + wy * math.cos(h)
        assert p["east"][k] == pytest.approx(east, abs=1e-5)
        assert p["north"][k] == pytest.approx(north, abs=1e-5)
        checked += 1
    assert checked == 5
    gps = process(raws["winriver01.PD0"], "gps")
    i = 120
    we, wn = rotate(gps.raw.vel[0], gps.raw.vel[1], gps.offset_applied)
    k = int(np.flatnonzero(np.isfinite(gps.cur_e[:, i]))[0])
    assert gps.cur_e[k, i] == pytest.approx(we[k, i] + gps.gps_e[i], abs=1e-9)
    assert gps.cur_n[k, i] == pytest.approx(wn[k, i] + gps.gps_n[i], abs=1e-9)


def test_winriver_compass_offset_makes_bottom_track_match_gps(raws):
    """The estimate (fix-to-fix displacements, closed form) against a brute-force scan of the
    offset that minimises the misfit between bottom-track and GPS velocities ensemble by ensemble,
    and against the provenance's "about -23 deg"."""
    raw = raws["winriver01.PD0"]
    s = process(raw)
    est = s.compass.offset_deg
    be, bn = -raw.vel_bt[0], -raw.vel_bt[1]
    ok = np.isfinite(be) & np.isfinite(s.gps_e)
    scan = np.arange(-60.0, 60.0, 0.05)
    cost = [
        np.sum((np.array(rotate(be[ok], bn[ok], d)) - [s.gps_e[ok], s.gps_n[ok]]) ** 2)
        for d in scan
    ]
    best = scan[int(np.argmin(cost))]
    assert abs(est - best) < 2.0, (est, best)
    assert abs(est - (-23.0)) < 2.0
    # with the offset applied, the bottom track's speed and course agree with the GPS's
    ce = np.degrees(np.arctan2(s.bt_e[ok], s.bt_n[ok]) - np.arctan2(s.gps_e[ok], s.gps_n[ok]))
    assert abs(np.median((ce + 180) % 360 - 180)) < 2.0


def test_rdi_withbt_gets_a_clear_verdict(raws):
    """dolfyn's 100 ensembles: no bottom-track lock and no GPS, so no velocity over ground and no
    current; the whole file has no GPS, so nothing it measures has a position."""
    from forcemap.host.convert.adcp_import import sample_rows
    from forcemap.host.convert.adcp_qa import findings

    s = process(raws["RDI_withBT.000"].head(100))
    assert not s.has_ground_velocity
    found = {f.check: f for f in findings(s)}
    verdict = found["no_ground_velocity"]
    assert verdict.verdict == "red"
    assert "no bottom-track lock" in verdict.message and "no GPS" in verdict.message
    rows = [r.to_json() for r in sample_rows(s)]
    assert all(r[c] is None for r in rows for c in r if c.startswith("current_"))
    assert all(r["lat"] is None for r in rows)
    full = process(raws["RDI_withBT.000"])
    assert np.isnan(full.lat).all()


def test_a_file_without_positions_exports_its_soundings_with_their_uncertainty(tmp_path):
    """RDI_withBT has no GPS: its table has soundings but no place. Export writes them, each with a TVU
    of its sounder and attitude (no slope term: a bed's slope needs a track), never a crash."""
    out = tmp_path / "bt.mcap"
    assert main(["import", str(_dir() / "RDI_withBT.000"), "-o", str(out)]) == 0
    csv_path = tmp_path / "bt.csv"
    assert main(["export", str(out), "-o", str(csv_path)]) == 0
    rows = list(csv.DictReader(csv_path.open()))
    assert rows and not any(r.get("lat") for r in rows)
    sounded = [r for r in rows if r["depth"]]
    assert len(sounded) > 0.5 * len(rows)

    def column(name: str) -> np.ndarray:
        return np.array([float(r[name]) if r[name] else np.nan for r in sounded])

    depth, tvu = column("depth"), column("depth_tvu")
    tilt = np.maximum(np.abs(column("roll")), np.abs(column("pitch")))
    assert np.isfinite(tvu).mean() > 0.9 and np.all(tvu[np.isfinite(tvu)] > 0)
    # held level, within a few percent of the depth; tilted tens of degrees (the file has such
    # ensembles), the attitude's term makes it larger
    level, tilted = np.isfinite(tvu) & (tilt < 5.0), np.isfinite(tvu) & (tilt > 20.0)
    assert level.sum() > 100 and np.all(tvu[level] < 0.1 * depth[level] + 0.5)
    assert tilted.any() and np.median(tvu[tilted]) > 2 * np.median(tvu[level])


def test_import_writes_findings_and_a_table_with_the_adcp_columns(tmp_path, capsys):
    out = tmp_path / "rp.mcap"
    assert main(["import", str(_dir() / "RiverPro_test01.PD0"), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "qa " in printed and "heading.compass_offset" in printed
    recs = [r for r in iter_records(out) if type(r).__name__ == "Metadata" and is_finding(r.name)]
    found = [QaFinding.from_metadata(dict(r.metadata)) for r in recs]
    assert {f.category for f in found} >= {"adcp", "heading", "position"}
    assert any(f.check == "compass_offset" and f.applied for f in found)
    _every_message_matches_its_schema(out)
    csv_path = tmp_path / "rp.csv"
    assert main(["export", str(out), "-o", str(csv_path)]) == 0
    rows = list(csv.DictReader(csv_path.open()))
    s = process(read_pd0(_dir() / "RiverPro_test01.PD0"))
    assert len(rows) == int(np.isfinite(s.davg_e).sum()) > 200  # the ensembles with a current
    for col in ("lat", "lon", "depth", "current_speed", "current_speed_davg", "boat_east"):
        assert col in rows[0]
    assert all(r["current_speed_davg"] for r in rows)
    # positions move as the boat's velocity says: GPS positions vs the integrated sog, within 20 %
    t = np.array([float(r["t"]) for r in rows])
    lat = np.array([float(r["lat"]) for r in rows])
    sog = np.array([float(r["sog"]) if r["sog"] else np.nan for r in rows])
    from forcemap.host.vessel.geodesy import LocalFrame

    f = LocalFrame(lat[0], float(rows[0]["lon"]))
    x, y = f.to_local(lat, np.array([float(r["lon"]) for r in rows]))
    step = np.diff(t) < 3.0  # consecutive ensembles
    path_len = np.sum(np.hypot(np.diff(x), np.diff(y))[step])
    run = np.nansum((sog[1:] * np.diff(t))[step])
    assert path_len == pytest.approx(run, rel=0.2)
    depth = np.array([float(r["depth"]) for r in rows if r["depth"]])
    assert 0.5 < np.median(depth) < 10 and np.median(np.abs(np.diff(depth))) < 0.5


def test_without_the_extra_a_pd0_gets_one_line_naming_the_install(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "mhkit", None)  # as if not installed: import fails
    rc = main(["import", str(_dir() / "winriver01.PD0"), "-o", str(tmp_path / "w.mcap")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert install_hint("adcp") in err[0] and "[adcp]" in err[0]
    assert not (tmp_path / "w.mcap").exists()


def test_damaged_ensembles_are_left_out_and_counted(raws, tmp_path, capsys):
    """Bytes flipped in a copy of winriver01: the ensembles whose checksum still holds read exactly
    as in the clean file; the rest are left out and counted. A file with one ensemble: one line."""
    data = bytearray((_dir() / "winriver01.PD0").read_bytes())
    rng = np.random.default_rng(7)
    for i in rng.integers(0, len(data), 40):
        data[i] ^= 0x5A
    bad = tmp_path / "damaged.PD0"
    bad.write_bytes(bytes(data))
    raw = read_pd0(bad)
    clean = raws["winriver01.PD0"]
    assert 0 < raw.n < clean.n and raw.skipped_bytes > 0
    k = np.searchsorted(clean.number, raw.number)
    assert np.array_equal(clean.number[k], raw.number)
    np.testing.assert_array_equal(raw.vel_raw, clean.vel_raw[..., k])
    out = tmp_path / "d.mcap"
    assert main(["import", str(bad), "-o", str(out)]) == 0
    assert "damaged bytes left out" in capsys.readouterr().out
    one = tmp_path / "one.PD0"
    one.write_bytes((_dir() / "winriver01.PD0").read_bytes()[:4000])
    assert main(["import", str(one), "-o", str(tmp_path / "one.mcap")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "at least 2" in err[0]


def test_gga_without_a_fix_never_sets_the_clock(raws):
    """Issue 60: RiverPro_test01's first 60 % of GGA made fixless (quality 0) and stamped by a
    receiver clock of 2009-02-21, as before a first fix: the clock on UTC is the one the fixes give
    (the untouched file's, within its jitter), and the GGA left out are counted in its timing."""
    from dataclasses import replace

    from forcemap.host.convert.adcp_import import _config

    raw = raws["RiverPro_test01.PD0"]
    clean = process(raw).clock
    k = int(0.6 * raw.t_gps.size)
    old_day = 1235174400.0  # 2009-02-21 00:00 UTC
    t_gps, fix = raw.t_gps.copy(), raw.fix.copy()
    t_gps[:k] = old_day + t_gps[:k] % 86400.0
    fix[:k] = 0
    s = process(replace(raw, t_gps=t_gps, fix=fix))
    assert s.clock.offset_s == pytest.approx(clean.offset_s, abs=max(clean.spread_s, 0.05))
    assert (s.clock.fixes, s.clock.without_fix) == (raw.t_gps.size - k, k)
    assert time_day(s.t[0]) == time_day(raw.t_gps[-1])  # the survey on its own day
    assert f"{k} GGA without a fix not used" in _config(s, "x.PD0")["timing"]


def time_day(t: float) -> int:
    return int(t // 86400)


def _every_message_matches_its_schema(mcap) -> None:
    n, names = validate_log_schemas(mcap)
    assert n > 272
    assert {"forcemap.AdcpSample", "forcemap.AdcpProfile", "foxglove.LocationFix"} <= names
