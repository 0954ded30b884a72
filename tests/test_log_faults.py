"""Issue 28's faults of real logs, on the simulator's NMEA-only boat where the truth is known: a compass
without variation (IGRF-14's declination is used and said), a bus whose checksums are computed over the
address only (recognised, reported with its count, accepted only with --nmea-checksum lenient), and a
log that opens with a minute of fixes 500 km away (flagged as jumps with their times, never used)."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.convert.log_info import scan_file
from forcemap.host.log.mcap import read_messages
from forcemap.host.vessel.geodesy import wrap_to_180
from forcemap.sim_devices.engine import Simulation

from tests.sim_sources import run, samples
from tests.tools import real_data

DURATION_S = 300.0


def capture(path: Path, faults: str, seed: int = 1) -> Simulation:
    """The bus's and the sounder's lines as a logger on a multiplexer writes them: whole lines,
    in the order they arrive, with no receive times (an NMEA capture file)."""
    sim = Simulation(scenario="river", faults=faults, seed=seed, nmea_bus=True)
    buf = {"nmea": b"", "depth": b""}
    with open(path, "wb") as f:

        def sink(source: str, t_ns: int, data: bytes) -> None:
            if source not in buf:
                return
            buf[source] += data
            *whole, buf[source] = buf[source].split(b"\n")
            f.writelines(line + b"\n" for line in whole)

        sim.run(DURATION_S, sink)
    return sim


def test_no_variation_takes_igrf_declination_and_says_it(tmp_path):
    from pyIGRF14 import igrf_value

    paths, truth, sim = run(tmp_path, "no_variation", duration_s=DURATION_S)
    sc = sim.scenario
    tm = time.gmtime(sc.t0)
    year = tm.tm_year + (tm.tm_yday - 1 + (sc.t0 % 86400) / 86400) / 365.0
    library = igrf_value(sc.lat0, sc.lon0, 0.0, year)[0]
    finding = scan_file(paths[-1]).findings["qa.heading.declination"]
    assert abs(finding.value - library) < 0.1, (finding.value, library)
    assert finding.applied and "IGRF-14 declination" in finding.message
    # the heading is there, and true: the samples' heading against the truth's (compass noise 1 deg)
    s = samples(paths)
    has = np.isfinite(s["heading"])
    assert has.mean() > 0.95
    true_heading = np.interp(s["t"][has], truth["t"], np.unwrap(np.radians(truth["heading"])))
    err = [
        wrap_to_180(a - math.degrees(b))
        for a, b in zip(s["heading"][has], true_heading, strict=True)
    ]
    assert abs(np.median(err)) < 0.3 and np.percentile(np.abs(err), 90) < 3.0
    # the current is there too (it needs the heading): the river's, not the boat's speed
    assert np.isfinite(s["current_east"]).mean() > 0.9


def _valid(line: bytes) -> bool:
    """The standard checksum: XOR of every character between $ and *."""
    body, _, cs = line[1:].partition(b"*")
    x = 0
    for c in body:
        x ^= c
    return cs[:2].upper() == f"{x:02X}".encode()


def test_a_checksum_variant_is_named_and_accepted_only_when_asked(tmp_path, capsys):
    log = tmp_path / "bus.nmea"
    capture(log, "checksum_variant")
    lines = log.read_bytes().splitlines()
    bus = [ln for ln in lines if not ln.startswith(b"$SD")]  # the sounder's checksums are right
    # over the address only, a sentence whose other characters XOR to 0 is right by chance
    variant = sum(not _valid(ln) for ln in bus)
    assert variant > 0.95 * len(bus) > 1000
    out = tmp_path / "out.mcap"
    assert main(["import", str(log), "-o", str(out)]) == 0  # the sounder's depth, little else
    text = capsys.readouterr().out
    said = [ln for ln in text.splitlines() if "computed over the address only" in ln]
    assert len(said) == 1 and f"checksums: {variant} of {len(lines)} lines" in said[0], text
    assert "rejected; --nmea-checksum lenient accepts them" in said[0]
    assert f"{variant} rejected {{'bad_checksum': {variant}}}" in text
    assert scan_file(out).findings["qa.other.nmea_checksum"].verdict == "red"
    assert main(["import", str(log), "-o", str(out), "--force", "--nmea-checksum", "lenient"]) == 0
    text = capsys.readouterr().out
    said = [ln for ln in text.splitlines() if "computed over the address only" in ln]
    assert len(said) == 1 and f"checksums: {variant} of {len(lines)} lines" in said[0], text
    assert "0 rejected" in text and "accepted (--nmea-checksum lenient)" in said[0]
    finding = scan_file(out).findings["qa.other.nmea_checksum"]
    assert finding.value == variant and finding.verdict == "yellow"
    # accepted, the bus gives the boat's positions: a fix a second
    fixes = [m.message for m in read_messages([out], "/fix")]
    assert len(fixes) > 0.9 * DURATION_S


def test_time_sentences_rejected_are_named_not_missing(tmp_path, capsys):
    """The real log whose bus computes its checksums over the address only: no RMC or GLL passes
    the standard checksum, and the error says so and gives the option."""
    log = real_data() / "nmea" / "irene" / "irene_2013-07-31_flensburg_checksums.nmea"
    assert main(["import", str(log), "-o", str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no time in this log" not in err
    assert "3712 RMC, 3703 GLL lines were all rejected" in err  # as PROVENANCE.md counts them
    assert "computed over the address only" in err and "--nmea-checksum lenient" in err


def test_a_log_that_opens_500_km_away_flags_the_jumps_and_keeps_the_track(tmp_path, capsys):
    log = tmp_path / "jump.nmea"
    sim = capture(log, "position_jump:at=0:for=60")
    out = tmp_path / "out.mcap"
    assert main(["import", str(log), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    finding = scan_file(out).findings["qa.position.jumps"]
    assert finding.value == sim.bus.jumped > 100  # every fix sent 500 km off, and no other
    assert finding.verdict in ("yellow", "red") and "flagged as jumps" in text
    # listed with its times: the first minute of the log
    t0 = time.strftime("%H:%M", time.gmtime(sim.scenario.t0))
    assert f"{t0}:00-{t0}:59 UTC" in finding.extra["stretches"], finding.extra
    # no fix 500 km away reached the log: every position is within 2 km of the survey's origin
    fixes = [m.message for m in read_messages([out], "/fix")]
    lat0 = sim.scenario.lat0
    assert fixes and max(abs(f["latitude"] - lat0) for f in fixes) < 0.02


@pytest.mark.parametrize("at", [150.0])
def test_jumps_in_the_middle_of_a_live_run(tmp_path, at):
    paths, _, sim = run(tmp_path, f"position_jump:at={at}:for=20", duration_s=DURATION_S)
    finding = scan_file(paths[-1]).findings["qa.position.jumps"]
    assert finding.value == sim.bus.jumped > 20
    s = samples(paths)
    assert np.nanmax(np.abs(s["lat"] - sim.scenario.lat0)) < 0.02


def test_run_takes_the_same_option():
    """`forcemap run --nmea-checksum lenient`: the daemon's pipeline parses leniently."""
    from forcemap.host.cli import build_parser
    from forcemap.host.cli.run import _pipeline_factory
    from forcemap.host.fuse.calibration import Calibration
    from forcemap.host.fuse.pipeline import NullSink

    args = build_parser("run").parse_args(
        ["run", "--nmea", "udp:10110", "--nmea-checksum", "lenient"]
    )
    assert args.nmea_checksum == "lenient"
    make = _pipeline_factory(Calibration(), "interpolate", 1.0, nmea_checksum=args.nmea_checksum)
    pipe = make(NullSink())
    line = b"$IIHDG,063,,,,*4B\r\n"  # the Irene bus's: the checksum of "IIHDG" alone
    pipe.feed("nmea", 1_000_000_000, 1_000_000_000, line)
    assert pipe.nmea.parser.accepted["HDG"] == 1 and pipe.nmea.parser.variants["address"] == 1
    strict = _pipeline_factory(Calibration(), "interpolate", 1.0)(NullSink())
    strict.feed("nmea", 1_000_000_000, 1_000_000_000, line)
    assert strict.nmea.parser.rejected["bad_checksum"] == 1


def _headings(variation_field: str, boat: float | None) -> tuple[list[float], list[str]]:
    """Ten seconds of RMC (its variation field as given) and a magnetic HDG of 100 deg without
    variation, at Lausanne on 2008-08-20, through the pipeline: the headings it logged, and the
    findings' names."""
    from forcemap.host.fuse.calibration import Calibration
    from forcemap.host.fuse.pipeline import ListSink, Pipeline
    from forcemap.sim_devices.nmea_sounder import sentence

    var = (variation_field, "E" if variation_field else "")
    sink = ListSink()
    pipe = Pipeline(Calibration(magnetic_variation_deg=boat), sink)
    t0 = 1219250400  # 2008-08-20 16:40:00 UTC
    for k in range(10):
        hms = time.strftime("%H%M%S", time.gmtime(t0 + k))
        rmc = (hms, "A", "4629.919", "N", "00639.938", "E", "4.0", "252", "200808", *var, "A")
        lines = [sentence("II", "RMC", rmc), sentence("II", "HDG", ("100", "", "", "", ""))]
        ns = (t0 + k) * 1_000_000_000
        pipe.feed("nmea", ns, ns, "".join(x + "\r\n" for x in lines).encode())
    pipe.close()
    found = [name for name, _ in sink.meta if name.startswith("qa.")]
    return [m["heading"] for m in sink.topic("/boat/state") if m["heading"] is not None], found


def test_the_logs_variation_and_the_boat_file_win_over_the_model():
    from pyIGRF14 import igrf_value

    igrf = igrf_value(46.4987, 6.6656, 0.0, 2008 + 232 / 366)[0]
    model, found = _headings("", None)
    assert model and abs(model[-1] - (100.0 + igrf)) < 0.01 and "qa.heading.declination" in found
    logged, found = _headings("1.5", None)
    assert logged and abs(logged[-1] - 101.5) < 1e-6 and "qa.heading.declination" not in found
    pinned, found = _headings("1.5", 3.0)
    assert pinned and abs(pinned[-1] - 103.0) < 1e-6 and "qa.heading.declination" not in found
