"""Navigation estimated from every source (issue 29), against the simulator's truth.

The simulated boat has two receivers (a precise one fixing every 4 s, a coarse one every second,
each sending RMC, GGA and GLL at their own instants and UTC stamps), a gyro compass 5 s late, an
on-time fluxgate and a rate-of-turn sensor. Its boat file keeps the latencies in the rows
(``[sync] latency = "keep"``), so one run serves both sides: the table with the latencies removed
(``remove_latency=True``) and the log's own table, with them kept.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.convert import nav_findings
from forcemap.host.convert.export import samples_table
from forcemap.host.log.mcap import read_messages
from forcemap.host.log.qa_records import QaFinding
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.survey import data_quality
from forcemap.host.workbench.survey.table import load_survey, survey_from_columns
from forcemap.host.workbench.terms import clock_offset

from tests import sim_sources

FAULTS = "nav_receivers,late_compass,rate_of_turn"
LATE = "nmea HEHDT"  # the gyro compass, 5 s late
ON_TIME = ("nmea HCHDG +variation", "nmea TIROT")
BOAT = '[sync]\nlatency = "keep"\n'


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("nav")
    paths, truth, _ = sim_sources.run(out, FAULTS, duration_s=600.0, boat_toml=BOAT)
    return paths, truth


def columns(table) -> dict[str, np.ndarray]:
    return {
        c: np.array([np.nan if v is None else v for v in table.column(c)]) for c in table.columns
    }


def test_rows_at_their_own_time_against_the_truth(run):
    paths, truth = run
    logged = columns(samples_table(paths, navigation="logged"))
    smoothed = columns(samples_table(paths, remove_latency=True))
    assert np.array_equal(logged["t"], smoothed["t"])  # no row lost, none added
    t = smoothed["t"]
    frame = LocalFrame(float(truth["lat"][0]), float(truth["lon"][0]))
    x, y = frame.to_local(smoothed["lat"], smoothed["lon"])
    tx, ty = frame.to_local(
        np.interp(t, truth["t"], truth["lat"]), np.interp(t, truth["t"], truth["lon"])
    )
    err = np.hypot(x - tx, y - ty)
    assert np.percentile(err, 95) <= 0.5
    speed = np.hypot(np.diff(x), np.diff(y)) / np.diff(t)
    true_sog = np.interp(0.5 * (t[1:] + t[:-1]), truth["t"], truth["sog"])
    assert np.median(true_sog) > 2.5  # the boat makes about 3 m/s
    assert np.percentile(np.abs(speed - true_sog), 95) <= 0.3
    # the logged rows carry the last fix of the 4-s receiver: speeds of 0 and of 4 times the truth
    lx, ly = frame.to_local(logged["lat"], logged["lon"])
    logged_speed = np.hypot(np.diff(lx), np.diff(ly)) / np.diff(t)
    assert np.percentile(np.abs(logged_speed - true_sog), 95) > 1.0


def test_latencies_measured(run):
    paths, _ = run
    found = {f.source: f for f in nav_findings.log_findings(paths)}
    late = found[LATE]
    assert late.check == "latency" and late.category == "heading"
    assert abs(late.value - 5.0) <= 0.3
    assert late.verdict == "red"  # kept in the rows by the boat file
    for name in ON_TIME:
        assert abs(found[name].value) <= 0.3
    assert found["nmea TIROT"].category == "rate_of_turn"
    # every source's noise, bias and outliers go with it
    assert {"noise", "bias", "outliers", "readings"} <= set(late.extra)
    assert float(found["nmea HCHDG +variation"].extra["noise"]) == pytest.approx(1.0, abs=0.3)


def test_findings_are_in_the_log_as_qa_records(run):
    """The import path writes them; a simulator's log (written live) has them computed when asked,
    and both give the same records."""
    paths, _ = run
    recs = nav_findings.log_findings(paths)
    again = [QaFinding.from_metadata(f.to_metadata()) for f in recs]
    assert [f.name for f in again] == [f.name for f in recs]
    assert any(f.name == f"qa.heading.latency.{LATE}" for f in recs)


def _survey(path: Path, table):
    cols = columns(table)
    return survey_from_columns(path, cols)


def test_latency_removed_leaves_no_clock_offset(run):
    paths, _ = run
    survey = _survey(Path(paths[0]), samples_table(paths, remove_latency=True))
    vt = survey.vector_target("current_speed")
    assert abs(clock_offset.scan_offset(survey, vt).offset_s) <= 1.0


def test_latency_kept_is_blamed_on_the_late_compass(run):
    """With the latency kept (the boat file), the data-quality findings diagnose shows first name
    the gyro compass and its measured latency, not the speed log or the GNSS."""
    paths, _ = run
    survey = load_survey(paths[0])
    assert survey.latencies[LATE]["removed"] is False
    lines = [
        f.line() for f in data_quality.findings(survey, ["current_speed"]) if f.kind == "latency"
    ]
    assert lines and "HE HDT" in lines[0] and "+5.0 s late" in lines[0]
    assert not any("speed log" in ln and "late" in ln.split("Advice")[0] for ln in lines[:1])


def test_who_is_late_says_when_nothing_tells(run):
    paths, _ = run
    survey = _survey(Path(paths[0]), samples_table(paths, navigation="logged"))
    assert survey.latencies == {}
    from forcemap.host.workbench.survey.instruments import Instruments

    text = data_quality._who_is_late(survey, Instruments.of(survey), "current", 5.0)
    assert "nothing in the log tells which" in text


def test_a_stale_fix_and_a_jump_are_outliers_not_states(run, tmp_path):
    """Readings far off the track (a jump of 300 m, a fix repeated 20 s later) get no weight."""
    from forcemap.host.convert import nav_readings
    from forcemap.host.convert.navigation import Navigation

    paths, truth = run
    readings = nav_readings.read(paths)
    src = readings["position"]["nmea GP* [hhmmss.ss 4dp]"]
    n = len(src.t)
    jump_at, stale_at = n // 3, 2 * n // 3
    lat, lon = src.v[jump_at][0], src.v[jump_at][1]
    src.v[jump_at] = [lat + 300 / 111_000, lon, None, None]
    src.v[stale_at] = list(src.v[stale_at - 60])
    t = np.array(samples_table(paths, navigation="logged").column("t"))
    nav = Navigation().fit(readings, t)
    st = nav.state(t)
    frame = LocalFrame(float(truth["lat"][0]), float(truth["lon"][0]))
    x, y = frame.to_local(st["lat"], st["lon"])
    tx, ty = frame.to_local(
        np.interp(t, truth["t"], truth["lat"]), np.interp(t, truth["t"], truth["lon"])
    )
    assert np.max(np.hypot(x - tx, y - ty)) < 3.0
    fit = next(f for f in nav.fits_ if f.source == src.name and f.quantity == "position")
    assert fit.outliers >= 2


def test_sim_bus_sends_each_sentence_at_its_own_stamp(run):
    paths, _ = run
    stamps: dict[str, list[float]] = {}
    for m in read_messages(paths, "/nmea/sentence"):
        text = m.message["text"]
        kind = text[1:6]
        if kind in ("GNRMC", "GNGGA", "GNGLL"):
            f = text.split(",")[5 if kind == "GNGLL" else 1]
            stamps.setdefault(kind, []).append(float(f[4:]) % 4.0)
    phases = {k: float(np.median(v)) for k, v in stamps.items()}
    assert math.isclose(phases["GNGGA"] - phases["GNRMC"], 0.3, abs_tol=0.06), phases
    assert math.isclose(phases["GNGLL"] - phases["GNGGA"], 0.3, abs_tol=0.06), phases


def test_an_import_writes_the_findings_into_the_log(run, tmp_path):
    """The capture of the simulated bus, imported as a text file: its times are the sentences' UTC
    spread between stamps, and the import writes each source's finding as a qa.* record."""
    from forcemap.host.convert.importers import import_to_mcap
    from forcemap.host.convert.navigation_table import log_metadata

    paths, _ = run
    capture = tmp_path / "bus.nmea"
    with open(capture, "w") as f:
        for m in read_messages(paths, "/nmea/sentence"):
            f.write(m.message["text"] + "\n")
    out = tmp_path / "bus.mcap"
    res = import_to_mcap(capture, out)
    record = log_metadata([out], f"qa.heading.latency.{LATE}")
    assert record, "no latency finding for the late compass in the imported log"
    late = QaFinding.from_metadata(record)
    assert abs(late.value - 5.0) <= 0.3 and late.applied
    assert any(n.startswith("navigation: nmea HEHDT") for n in res.notes)


def test_log_info_lists_each_source(run, capsys):
    from forcemap.host.cli import main

    paths, _ = run
    assert main(["log", "info", str(paths[0])]) == 0
    out = capsys.readouterr().out
    assert "navigation sources" in out
    line = next(ln for ln in out.splitlines() if "nmea HEHDT:" in ln)
    assert "latency +5.0" in line and "noise" in line and "outliers" in line


def test_boat_file_sync_keys():
    from forcemap.host.fuse import calibration

    cal = calibration.loads('[sync]\nnavigation = "logged"\nlatency = "keep"\n')
    assert (cal.navigation, cal.latency) == ("logged", "keep")
    with pytest.raises(calibration.ConfigError, match="sync.latency"):
        calibration.loads('[sync]\nlatency = "later"\n')


def test_diagnose_explains_a_clock_offset_by_the_late_compass(run):
    """diagnose's clock-offset explanation names the source the measured latencies show late."""
    from forcemap.host.workbench.diagnose.result import Candidate, explain_candidate
    from forcemap.host.workbench.survey.instruments import Instruments

    paths, _ = run
    inst = Instruments.of(load_survey(paths[0]))
    c = Candidate("clock_offset", "clock_offset(-5.00 s)", 1.0, 0.2, 1e-4, 0.2, None, False)
    text = explain_candidate(c, "", "current", 0.1, [], inst)
    assert "the measured latencies name the compass (HE HDT), +5.0 s late" in text
