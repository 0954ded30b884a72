"""Soundings on real logs (issue 37), by physical properties any correct pipeline has.

- PacCupStartNMEA.txt: the yacht reaches the Golden Gate channel (80-110 m) in the capture's last minutes
  and its damped sounder loses the bottom: it glides from 1.8 m (its own ringing) to 108 m and back
  within 40 m of travel. The stretch is found at import, every row is kept and marked, the bed is
  continuous where the sounder held it, and no map cell is made from the stretch.
- bundg_zeus_9.log: a B&G Zeus's XDR carries HEEL and TRIM; a sailing yacht heels to leeward; its DPT
  states the transducer's depth (0.4 m) that its DBT leaves out.

No real capture here has the hull's attitude and crossings both (bundg_zeus_9 is 2.5 minutes on one
course): the tilt correction's gain at crossings is shown on the simulator (test_soundings_sim.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.fuse.bottom_lost import path_tolerance
from forcemap.host.workbench.depth.surface import CAPTURE
from forcemap.host.workbench.survey.spikes import target_spikes
from forcemap.host.workbench.survey.table import load_survey

from tests.tools import csv_rows

PACCUP = "nmea/PacCupStartNMEA.txt"
BUNDG = "nmea/bundg_zeus_9.log"
SEABED_SLOPE = 0.5  # a seabed falls or climbs less than 1 in 2 between two soundings


def _imported(built) -> dict:
    """A real log as the run's shared cases import, export and check it (tests/real_cases.py)."""
    header, rows = csv_rows(built.csv)
    cols = {
        h: np.array([float(r[i]) if r[i] else np.nan for r in rows]) for i, h in enumerate(header)
    }
    return {"mcap": built.mcap, "csv": built.csv, "cols": cols, "check": built.check()}


@pytest.fixture(scope="module")
def paccup(real_case):
    return _imported(real_case(PACCUP))


@pytest.fixture(scope="module")
def bundg(real_case):
    return _imported(real_case(BUNDG))


def _finding(check: dict, check_name: str, category: str = "depth") -> dict:
    (f,) = [f for f in check["categories"][category]["findings"] if f["check"] == check_name]
    return f


def test_the_golden_gate_crossing_is_the_bottom_lost_found_at_import(paccup):
    c = paccup["cols"]
    f = _finding(paccup["check"], "bottom_lost")
    assert f["verdict"] in ("yellow", "red") and f["applied"]
    ((a, b),) = [tuple(map(float, s.split("-"))) for s in f["extra"]["stretches"].split(";")]
    t0 = c["t"][0]
    # in the capture's last minutes, where the track reaches the channel
    assert (a - t0) / 60 > 25 and (c["t"][-1] - b) / 60 < 2
    # every row kept, and marked: 1 inside the stretch, 0 outside
    inside = (c["t"] >= a) & (c["t"] <= b)
    assert np.array_equal(c["bottom_lost"] == 1, inside) and np.all(c["bottom_lost"][~inside] == 0)
    assert paccup["check"]["rows"] == len(c["t"])  # the log's rows, all in the table
    # in the stretch the soundings climb and fall by tens of metres, both ways, faster than a seabed
    x, y = _xy(c)
    step = np.hypot(np.diff(x), np.diff(y))
    dz = np.diff(c["depth"])
    beyond = np.abs(dz) - path_tolerance(c["depth"][1:]) - SEABED_SLOPE * step
    inner = inside[1:] & inside[:-1]
    assert (
        dz[inner & (beyond > 0) & (dz > 0)].sum() > 100
        and dz[inner & (beyond > 0) & (dz < 0)].sum() < -100
    )


def _xy(c: dict) -> tuple[np.ndarray, np.ndarray]:
    from forcemap.host.vessel.geodesy import LocalFrame

    return LocalFrame(float(np.median(c["lat"])), float(np.median(c["lon"]))).to_local(
        c["lat"], c["lon"]
    )


def test_where_the_sounder_held_the_bottom_the_bed_is_continuous(paccup):
    """Between successive soundings the sounder held (not in the stretch, not a spike), the bed changes
    no faster than a seabed can against the distance travelled (the spike floor plus 1 in 2)."""
    survey = load_survey(paccup["csv"])
    spikes = target_spikes(survey, "depth")
    held = ~spikes.flagged & (np.nan_to_num(survey.columns["bottom_lost"]) == 0)
    d, xy = survey.columns["depth"][held], survey.xy[held]
    step = np.hypot(*np.diff(xy, axis=0).T)
    jump = np.abs(np.diff(d)) > path_tolerance(d[1:]) + SEABED_SLOPE * step
    assert held.sum() > 0.8 * survey.n and jump.mean() < 0.005, (held.sum(), jump.sum())
    # the stretch's rows are all flagged, with the stretch's own words
    assert np.all(spikes.flagged[np.nan_to_num(survey.columns["bottom_lost"]) == 1])
    assert any("bottom lost" in line for line in spikes.lines())


def test_no_map_cell_is_made_from_the_lost_stretch(paccup, tmp_path):
    import xarray as xr
    from pyproj import Transformer

    out = tmp_path / "maps.nc"
    assert main(["grid", str(paccup["csv"]), "-o", str(out), "--target", "depth", "--quiet"]) == 0
    ds = xr.open_dataset(out)
    survey = load_survey(paccup["csv"])
    kept = ~target_spikes(survey, "depth").flagged
    lat, lon = survey.columns["lat"], survey.columns["lon"]
    epsg = int(ds.attrs["geospatial_crs"].split()[0].removeprefix("EPSG:"))
    e, n = Transformer.from_crs(4326, epsg, always_xy=True).transform(lon, lat)
    ee, nn = np.meshgrid(ds["x"].values, ds["y"].values)
    cells = np.column_stack([ee.ravel(), nn.ravel()])
    from scipy.spatial import cKDTree

    near_kept, _ = cKDTree(np.column_stack([e, n])[kept]).query(cells)
    res = float(ds.attrs["resolution_m"])
    surface = ds["depth_surface"].values.ravel()
    soundings = ds["depth_surface_soundings"].values.ravel()
    made = np.isfinite(surface)
    assert made.sum() > 100 and np.all(soundings[made] >= 1)
    assert np.all(near_kept[made] <= CAPTURE * res + 1e-6)  # every surface cell from kept soundings
    # ... and the GP's cells too: none farther from every kept sounding than the mask distance
    gp = np.isfinite(ds["depth"].values.ravel())
    mask_m = _mask_distance(ds)
    assert np.all(near_kept[gp] <= mask_m + res)
    # the lost stretch lies over the channel: cells near it alone are empty in both
    lost = np.nan_to_num(survey.columns["bottom_lost"]) == 1
    near_lost, _ = cKDTree(np.column_stack([e, n])[lost]).query(cells)
    only_lost = (near_lost < res) & (near_kept > mask_m + res)
    assert only_lost.sum() > 0 and not (made | gp)[only_lost].any()


def _mask_distance(ds) -> float:
    return float(ds.attrs["comment"].split("farther than ", 1)[1].split(" m", 1)[0])


def test_s44_shares_in_check_and_the_report(paccup):
    from forcemap.host.report.build import ReportContext, qa_section

    f = _finding(paccup["check"], "s44")
    special = float(f["extra"]["special_share"])
    assert 0 <= special <= f["value"] <= 100  # Special is stricter than Order 1a/1b
    assert "Order 1a/1b" in f["message"] and "Special" in f["message"]
    assert "where the bottom was lost left out" in f["message"]
    html = "".join(qa_section(ReportContext(paccup["mcap"], None, None, [], {})))  # type: ignore[arg-type]
    assert "IHO S-44" in html and "Order 1a/1b" in html


def test_a_yacht_heels_to_leeward_and_its_xdr_says_so(bundg):
    c = bundg["cols"]
    roll, awa = c["roll"], c["app_wind_angle"]
    ok = np.isfinite(roll) & np.isfinite(awa)
    assert ok.mean() > 0.9 and np.all(np.abs(roll[ok]) < 20)
    # wind on the starboard bow (apparent 49-87 deg): the hull heels to port, roll < 0 on the whole
    assert np.all(awa[ok] > 0) and np.median(roll[ok]) < 0
    assert np.isfinite(c["pitch"]).mean() > 0.9
    # 2.5 minutes on one course: no crossing to estimate a beam angle from, and it says so
    tilt = _finding(bundg["check"], "tilt")
    assert "not estimated" in tilt["message"] and "crossings" in tilt["message"]


def test_dpt_against_dbt_of_one_transducer_is_its_stated_depth(bundg):
    """DPT states the transducer 0.4 m below the surface and DBT leaves it out: sounder against sounder
    finds that offset, and no stretch where they disagree beyond it."""
    (f,) = [
        f for f in bundg["check"]["categories"]["depth"]["findings"] if f["check"] == "sounders"
    ]
    assert f["source"] == "nmea SDDBT" and f["value"] == pytest.approx(-0.4, abs=0.05)
    assert float(f["extra"]["disagree_share"]) < 0.05 and not f["extra"]["stretches"]
    assert "offset_m" in f["fix"]
