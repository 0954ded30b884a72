"""The tide on a reference current (terms/reference_tide.py, targets/reference_part.py, survey/reference.py).

On a synthetic survey of two days whose current is a NOAA station's prediction times a ratio and later by
an offset that change along the reach, `fit --effects tide --reference-current` must recover both and
predict a third day; without a reference `tide` stays the harmonic fit; a term on a reference without one
is one clear line; several tables are one survey; the commands take the options.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.vessel.reference_current import read_reference
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.reference import load_reference, with_reference
from forcemap.host.workbench.survey.several import load_surveys
from forcemap.host.workbench.survey.table import is_circular, load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms import registry, time_terms
from forcemap.host.workbench.terms.reference_tide import OMEGA, relation
from forcemap.host.workbench.terms.spec import BASELINE

NOAA = Path(__file__).parent / "data" / "real" / "tides" / "noaa_sfbay_currents.json"
STATION = "SFB1204"
T0 = 1_780_300_800.0  # 2026-06-01 08:00 UTC
LAT0, LON0 = 37.81, -122.43


def ratio_offset(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The synthetic truth: ratio 0.7-1.1 and offset 10-40 min from west to east over 1.2 km."""
    xi = np.clip(x / 600.0, -1, 1)
    return 0.9 + 0.2 * xi, 60.0 * (25.0 + 15.0 * xi)


def write_day(path: Path, day: int, seed: int, stw: bool = False) -> Path:
    """One day's samples table (a row every 20 s, 06-20 h): a boat going back and forth along the reach
    in the station's flood (east) direction, the current the truth plus 0.05 m/s noise."""
    rng = np.random.default_rng(seed)
    t = T0 + day * 86400.0 + np.arange(0.0, 14 * 3600.0, 20.0)
    x = 600.0 * np.sin(2 * np.pi * (t - T0) / 2400.0)
    y = 150.0 * np.sin(2 * np.pi * (t - T0) / 1700.0)
    st = read_reference(NOAA).stations[STATION]
    ratio, offset = ratio_offset(x)
    v = ratio * st.speed(t - offset)
    a = math.radians(st.flood_dir)
    e = v * math.sin(a) + rng.normal(0, 0.05, len(t))
    n = v * math.cos(a) + rng.normal(0, 0.05, len(t))
    lat, lon = LocalFrame(LAT0, LON0).to_latlon(x, y)
    cols = {"t": t, "lat": lat, "lon": lon, "current_east": e, "current_north": n}
    if stw:  # the boat stopped at a berth for the first hour: the log reads nothing, "current" 0
        speed = np.where(t - t[0] < 3600.0, 0.0, 2.5)
        cols["stw"] = speed
        cols["current_east"] = np.where(speed > 0, e, 0.0)
        cols["current_north"] = np.where(speed > 0, n, 0.0)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(list(cols))
        w.writerows(np.column_stack(list(cols.values())).tolist())
    return path


@pytest.fixture(scope="module")
def days(tmp_path_factory) -> list[Path]:
    d = tmp_path_factory.mktemp("reference")
    return [write_day(d / f"day{i}.csv", i, i) for i in range(3)]


def fitted(tables: list[Path]) -> SurveyModel:
    s = load_surveys([str(p) for p in tables])
    with_reference(s, load_reference(NOAA, STATION))
    return SurveyModel(s, "current_speed", [*BASELINE, "tide"]).fit()


def test_tide_becomes_the_relation_on_a_reference_and_stays_harmonic_without() -> None:
    tide = registry.parse_term("tide", is_circular)
    rel = registry.with_reference(tide)
    assert str(rel) == "tide(reference, position)" and registry.caps(rel).along_reference
    assert not registry.caps(rel).is_level and registry.caps(rel).predicts_in_time
    named = registry.parse_term("tide(M2, K1)", is_circular)
    assert registry.with_reference(named) is named  # constituents asked for stay the harmonic fit
    assert str(registry.parse_term("tide(reference)", is_circular)) == "tide(reference)"
    with pytest.raises(WorkbenchError, match="takes its constituents from the reference"):
        registry.parse_term("tide(reference, M2)", is_circular)
    assert math.isclose(relation(1.0, 0.0)[0], 1.0) and relation(1.0, 0.0)[1] == 0.0
    ratio, offset = relation(0.8 * math.cos(0.3), -0.8 * math.sin(0.3))
    assert math.isclose(ratio, 0.8) and math.isclose(offset, 0.3 / OMEGA)


def test_two_days_recover_the_ratio_and_offset_and_predict_the_third(days) -> None:
    sm = fitted(days[:2])
    assert "tide(reference, position)" in sm.terms and sm.axis.to_json()["stations"] == [STATION]
    s = sm.survey
    xy = s.xy[:: max(1, s.n // 400)]
    maps = time_terms.relation_at(sm, xy)
    ratio, offset = ratio_offset(xy[:, 0])
    core = np.abs(xy[:, 0]) < 500.0  # the reach's ends are where the boat turns
    assert np.abs(maps["ratio"][core] / ratio[core] - 1).max() < 0.1
    assert np.abs(maps["offset_s"][core] - offset[core]).max() < 600.0
    assert set(maps["station"]) == {STATION}
    day3 = load_survey(days[2])
    x, y = LocalFrame(s.lat0, s.lon0).to_local(day3.columns["lat"], day3.columns["lon"])
    p = sm.predict_grid(np.column_stack([x, y]), at=day3.columns["t"])
    err = np.hypot(p["east"] - day3.columns["current_east"], p["north"] - day3.columns["current_north"])
    assert math.sqrt(np.mean(err**2)) < 0.15
    lines = time_terms.describe(sm)
    assert any("station SFB1204 for every place" in line for line in lines)
    assert any(line.strip().startswith("flood: ratio") for line in lines)


def test_without_a_reference_tide_is_the_harmonic_fit(days) -> None:
    sm = SurveyModel(load_survey(days[0]), "current_speed", [*BASELINE, "tide"]).fit()
    assert sm.terms[-1] == "tide" and time_terms.tide_summary(sm)["constituents"]
    with pytest.raises(WorkbenchError, match="needs a reference current"):
        SurveyModel(load_survey(days[0]), "current_speed", [*BASELINE, "tide(reference)"]).fit()


def test_a_stalled_speed_log_is_left_out_of_the_relation(tmp_path: Path) -> None:
    s = load_survey(write_day(tmp_path / "berth.csv", 0, 5, stw=True))
    with_reference(s, load_reference(NOAA, STATION))
    sm = SurveyModel(s, "current_speed", [*BASELINE, "tide"])
    assert sm.rows.stalled == 180 and any("slower than 0.5 m/s" in line for line in sm.rows.lines())
    assert sm.survey.n == s.n - 180


def test_several_tables_are_one_survey(days) -> None:
    one = load_surveys([days[0], days[1]])
    a, b = load_survey(days[0]), load_survey(days[1])
    assert one.n == a.n + b.n and np.all(np.diff(one.columns["t"]) > 0)
    assert one.source == days[0] and any("2 tables as one survey" in n for n in one.notes)
    with pytest.raises(WorkbenchError, match="given twice"):
        load_surveys([days[0], days[0]])


def test_the_commands_take_a_reference_current(days, tmp_path: Path, capsys) -> None:
    table = tmp_path / "day.csv"
    table.write_bytes(days[0].read_bytes())
    rc = main(["fit", str(table), str(days[1]), "--target", "current_speed", "--effects", "tide",
               "--reference-current", str(NOAA), "--reference-station", STATION, "--no-plots",
               "--quiet", "--json", str(tmp_path / "fit.json")])  # fmt: skip
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "tide: reference current noaa_sfbay_currents.json: station SFB1204" in out
    report = json.loads((tmp_path / "fit.json").read_text())
    assert report["terms"][-1] == "tide(reference, position)"
    ref = ["--reference-current", str(NOAA), "--reference-station", STATION]
    nc = tmp_path / "maps.nc"
    assert main(["grid", str(table), str(days[1]), "-o", str(nc), "--target", "current_speed",
                 "--resolution", "40", "--quiet", *ref]) == 0  # fmt: skip
    import xarray as xr

    with xr.open_dataset(nc) as ds:
        assert {"current_ratio", "current_offset", "current_ratio_sd"} <= set(ds.data_vars)
        assert ds["current_offset"].attrs["units"] == "s"
    html = tmp_path / "report.html"
    assert main(["report", str(table), "-o", str(html), "--quiet", *ref]) == 0
    assert "The tide on the reference current" in html.read_text()
    capsys.readouterr()
    assert main(["fit", str(table), "--target", "current_speed", "--reference-station", STATION]) == 2
    assert "--reference-station needs --reference-current" in capsys.readouterr().err
    none = str(tmp_path / "none.json")
    assert main(["fit", str(table), "--target", "current_speed", "--reference-current", none]) == 2
    assert "--reference-current: cannot read" in capsys.readouterr().err
