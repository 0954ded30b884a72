"""A reference current read from NOAA's harmonic constants or a predicted series (host/vessel/reference_current.py).

NOAA's constants of 12 San Francisco Bay current stations (tests/data/real/tides/, PROVENANCE.md) predict
through the nodal corrections checked against UTide; the predictions must show the two logged days as
they were (2014-05-17: a spring flood on the City Front from 17:30 to 21:30 UTC, the yacht's own current
floods east then; 2014-05-10: a neap, within about +-0.5 m/s at the central-bay stations). A series as a
tide program exports it reads back to the same prediction, and every wrong file is one clear line.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.vessel import tides
from forcemap.host.vessel.reference_current import KNOT, read_reference
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.reference import load_reference

NOAA = Path(__file__).parent / "data" / "real" / "tides" / "noaa_sfbay_currents.json"


def utc(text: str) -> float:
    return datetime.fromisoformat(text).replace(tzinfo=UTC).timestamp()


def test_noaa_constants_predict_through_utides_nodal_corrections() -> None:
    ref = read_reference(NOAA)
    assert len(ref.ids) == 12 and ref.chosen is None
    st = ref.stations["SFB1201"]
    # NOAA's M1 and 2MK3 are UTide's NO1 and MO3; knots are converted to m/s
    assert {"NO1", "MO3"} <= set(st.constituents) and len(st.constituents) == 25
    assert math.isclose(st.amplitude[st.constituents.index("M2")], 2.359 * KNOT)
    t = utc("2014-05-17T19:00:00") + np.arange(0.0, 86400.0, 600.0)
    F, U, V = tides.fuv(t, st.constituents, st.lat)
    by_hand = st.z0 + (F * st.amplitude * np.cos(2 * np.pi * (V + U) - np.radians(st.phase_deg))).sum(1)
    assert np.allclose(st.speed(t), by_hand)
    # the rate is the prediction's derivative
    assert np.allclose(st.rate(t)[1:-1], np.gradient(st.speed(t), t)[1:-1], atol=1e-6)


def test_the_predictions_show_both_logged_days_as_they_were() -> None:
    ref = read_reference(NOAA)
    central = ("SFB1203", "SFB1204", "SFB1205")
    flood = np.arange(utc("2014-05-17T18:00:00"), utc("2014-05-17T21:00:01"), 900.0)
    for sid in central:  # a spring flood on the City Front through the yacht's afternoon
        assert ref.stations[sid].speed(flood).min() > 0.3, sid
    neap = np.arange(utc("2014-05-10T15:00:00"), utc("2014-05-10T23:00:01"), 900.0)
    for sid in central:  # a neap a week before: weaker everywhere
        assert np.abs(ref.stations[sid].speed(neap)).max() < 0.85, sid
        assert np.abs(ref.stations[sid].speed(neap)).max() < ref.stations[sid].speed(flood).max()


def test_each_place_takes_its_nearest_station_unless_one_is_chosen() -> None:
    ref = read_reference(NOAA)
    lat, lon = np.array([37.8143, 37.872, 37.79]), np.array([-122.432, -122.442, -122.374])
    assert [ref.ids[i] for i in ref.station_index(lat, lon)] == ["SFB1204", "SFB1212", "SFB1217"]
    one = ref.choose("sfb1205")
    assert one.chosen == "SFB1205" and set(one.station_index(lat, lon)) == {ref.ids.index("SFB1205")}
    with pytest.raises(ValueError, match="no station 'XYZ'"):
        ref.choose("XYZ")


def test_a_series_as_a_tide_program_exports_it_reads_back(tmp_path: Path) -> None:
    st = read_reference(NOAA).stations["SFB1204"]
    t = np.arange(utc("2014-05-17T12:00:00"), utc("2014-05-18T00:00:01"), 360.0)
    path = tmp_path / "noaa_export.csv"
    lines = ["# station: SFB1204 Alcatraz Island, SW of", "# lat: 37.81425", "# lon: -122.432",
             "Time (GMT), Velocity_Major (knots), meanFloodDir"]  # fmt: skip
    for ti, v in zip(t, st.speed(t) / KNOT, strict=True):
        when = datetime.fromtimestamp(ti, UTC).strftime("%Y-%m-%d %H:%M")
        lines.append(f"{when}, {v:.3f}, {st.flood_dir}")
    path.write_text("\n".join(lines) + "\n")
    ref = read_reference(path)
    series = ref.stations["SFB1204"]
    assert series.form == "time series" and series.lat == pytest.approx(37.81425)
    inside = np.linspace(t[1], t[-2], 97)
    assert np.abs(series.speed(inside) - st.speed(inside)).max() < 0.003  # the export's rounding
    assert np.abs(series.rate(inside) - st.rate(inside)).max() < 2e-6
    assert np.isnan(series.speed(np.array([t[-1] + 3600.0]))).all()  # no prediction beyond it


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("time,speed_kn,flood_dir\n2014-05-17 12:00,1,70\n2014-05-17 12:06,1,70\n",
         "has no zone"),
        ("time,speed,flood_dir\n2014-05-17T12:00Z,1,70\n2014-05-17T12:06Z,1,70\n", "unit"),
        ("time,speed_kn\n2014-05-17T12:00Z,1\n2014-05-17T12:06Z,1\n2014-05-17T12:12Z,1\n"
         "2014-05-17T12:18Z,1\n", "no flood direction"),
        ("when,how\n1,2\n3,4\n", "needs a time column and a speed column"),
        ('{"stations": {"A": {"lat": 1}}}', "has no 'constituents'"),
        ('{"stations": {"A": {"lat": 1, "lon": 2, "flood_dir": 3, "constituents": '
         '[{"name": "ZZ9", "amplitude": 1, "phase": 0}]}}}', "unknown tidal constituent"),
    ],
)  # fmt: skip
def test_a_wrong_reference_file_is_one_clear_line(tmp_path: Path, text: str, words: str) -> None:
    path = tmp_path / ("ref.json" if text.startswith("{") else "ref.csv")
    path.write_text(text)
    with pytest.raises(WorkbenchError, match=words) as e:
        load_reference(path)
    assert "\n" not in str(e.value) and str(e.value).startswith("--reference-current")
