"""Position sources ranked by their fix (issue 20): fix class and a clearly worse HDOP first, then
precision and the other rules; live, with a dwell so that a hesitating fix does not flap; the boat
file still overrides. On the simulator (two receivers, known truth) and on the real captures."""

from __future__ import annotations

import json
from collections import Counter
from functools import reduce
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.convert.importers import import_file
from forcemap.host.decode.nmea import NmeaParser
from forcemap.host.fuse import fix_quality as fq
from forcemap.host.fuse.pipeline import ListSink, Pipeline
from forcemap.host.fuse.sources import DWELL_S, WHY, SourceSelector
from forcemap.host.log.mcap import read_messages
from forcemap.sim_devices.nmea_sounder import sentence

from tests.sim_sources import figures, run
from tests.tools import REAL

A, B = "nmea GP* [hhmmss.ss 5dp]", "nmea GN* [hhmmss.ss 4dp]"
RMC_A, RMC_B = "nmea GPRMC [hhmmss.ss 5dp]", "nmea GNRMC [hhmmss.ss 4dp]"
POS = (47.0, 8.0, 1.0, 90.0)


def test_fix_classes_and_a_clearly_worse_hdop():
    assert fq.gga_fix(2) == fq.DGPS and fq.gga_fix(4) == fq.RTK_FIXED and fq.gga_fix(6) == 1
    assert fq.mode_fix("D") == fq.DGPS and fq.mode_fix("e") == fq.ESTIMATED
    assert fq.mode_fix(None) is None and fq.gsa_fix(2) == fq.FIX_2D and fq.mav_fix(6) == 6
    assert fq.compare((fq.DGPS, 2.0), (fq.GPS, 0.8)) < 0  # the class first, whatever the HDOP
    assert fq.compare((fq.GPS, 0.9), (fq.GPS, 2.1)) < 0
    assert fq.compare((fq.GPS, 0.9), (fq.GPS, 1.1)) == 0  # within the band: not clearly worse
    assert fq.compare((fq.GPS, 0.4), (fq.GPS, 0.7)) == 0  # 1.75x, but only 0.3 more
    assert fq.compare((None, 0.9), (fq.DGPS, None)) == 0  # nothing to compare: other rules decide
    assert fq.describe((fq.DGPS, 0.9)) == "DGPS, HDOP 0.9" and fq.describe((None, None)) == ""


RELAY = "nmea IIRMC [hhmmss 3dp]"


def _two_receivers(quality_a, quality_b, seconds: float = 300.0, sel=None):
    """Both receivers at 1 Hz (B half a second after A); ``quality_x(t)`` -> (class, HDOP). The
    instrument bus relays a fix between them, saying nothing of its quality (it never wins, and
    its readings must not reset a better receiver's dwell)."""
    sel = sel or SourceSelector()
    used = []
    for k in range(int(seconds)):
        for name, group, quality, dt in ((RMC_A, A, quality_a, 0.0), (RMC_B, B, quality_b, 0.5)):
            t = k + dt
            fix, hdop = quality(t)
            sel.report_fix(group, "GGA", t, fix, hdop)
            if sel.accept("position", name, t, POS, group):
                used.append((t, group))
            relay = "nmea II* [hhmmss 3dp]"
            assert not sel.accept("position", RELAY, t + 0.25, POS, relay)
    return sel, used


def _handovers(used):
    return [(t, g) for i, (t, g) in enumerate(used) if i == 0 or used[i - 1][1] != g]


def test_a_better_fix_wins_over_precision_and_a_degraded_one_hands_over_and_back():
    """B (4 decimals) is DGPS, A (5 decimals) autonomous: B from its first reading. B loses its
    corrections from 100 s to 200 s (autonomous, HDOP 4.5 against A's 2.1): A after DWELL_S."""

    def b(t):
        return (fq.GPS, 4.5) if 100 <= t < 200 else (fq.DGPS, 0.9)

    sel, used = _two_receivers(lambda t: (fq.GPS, 2.1), b)
    # both autonomous from 100 s: the HDOP decides once B's median of its last 10 s is 4.5 (its
    # 6th reading, 105.5 s), A's next reading starts the dwell; B's DGPS decides at once at 200.5 s
    assert _handovers(used) == [(0.0, A), (0.5, B), (106.0 + DWELL_S, A), (200.5 + DWELL_S, B)]
    assert sel.switches["position"] == 3
    assert sel.reason("position") == "the better fix: DGPS, HDOP 0.9 vs GPS, HDOP 2.1 of " + A


def test_a_hesitating_fix_or_a_small_hdop_difference_does_not_flap():
    """A flips between DGPS and dead reckoning every 4 s; B is a steady GPS: without the dwell the
    position would change receiver every 4 s. An HDOP 1.3 against 0.9 is inside the band."""

    def a(t):
        return (fq.DGPS, 0.9) if int(t) // 4 % 2 else (fq.ESTIMATED, 0.9)

    sel, used = _two_receivers(a, lambda t: (fq.GPS, 0.9))
    assert sel.switches["position"] <= 1 and len(_handovers(used)) <= 2
    sel, used = _two_receivers(lambda t: (fq.GPS, 1.3), lambda t: (fq.GPS, 0.9))
    assert _handovers(used) == [(0.0, A)]  # A by its decimals: the HDOPs do not decide
    assert sel.reason("position") == WHY["quality"] + "; fix GPS, HDOP 1.3"


def test_the_boat_file_overrides_the_fix():
    sel = SourceSelector({"position": ["GPRMC"]})
    sel, used = _two_receivers(lambda t: (fq.GPS, 2.1), lambda t: (fq.RTK_FIXED, 0.6), 60, sel)
    assert {g for _, g in used} == {A}
    assert sel.reason("position") == WHY["priority"] + "; fix GPS, HDOP 2.1"


def test_the_autopilots_gps_raw_int_says_how_good_its_global_position_is():
    sel = SourceSelector()
    sel.report_fix("mavlink GPS_RAW_INT", "GPS_RAW_INT", 0.0, fq.mav_fix(6), 0.7)
    assert sel.accept("position", "mavlink GLOBAL_POSITION_INT", 0.1, POS)
    assert sel.quality("mavlink GLOBAL_POSITION_INT") == (fq.RTK_FIXED, 0.7)
    assert sel.reason("position") == WHY["only"] + "; fix RTK fixed, HDOP 0.7"


def _line(talker: str, kind: str, fields: tuple[str, ...]) -> bytes:
    return (sentence(talker, kind, fields) + "\r\n").encode()


def test_gsa_and_the_rmc_mode_through_the_pipeline():
    """Two receivers, each with an RMC (mode A) and a GSA: the GSA counts for the receiver whose
    position came last on its talker; HDOP 3.0 against 0.8 chooses the 4-decimal one."""
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    t0 = 1_780_000_000.0
    sats = ("01", "02", "03", "04", "05", "06", "", "", "", "", "", "")
    for k in range(30):
        t = t0 + k
        hms = f"{int(t % 86400 // 3600):02d}{int(t % 3600 // 60):02d}{t % 60:05.2f}"
        data = b""
        for talker, lat, hdop in (("GP", "4700.00000", "3.0"), ("GN", "4700.0000", "0.8")):
            fields = (hms, "A", lat, "N", "00800.0000", "E", "2.0", "90.0", "010626", "", "", "A")
            data += _line(talker, "RMC", fields)
            data += _line(talker, "GSA", ("A", "3", *sats, "1.5", hdop, "1.1"))
        ns = int(t * 1e9)
        pipe.feed("nmea", ns, ns, data)
    pipe.close()
    meta = json.loads(dict([m for m in sink.meta if m[0] == "sources"][-1][1])["position"])
    assert meta["chosen"] == "nmea GNRMC [hhmmss.ss 4dp]"
    assert (
        meta["why"] == "the better fix: GPS, HDOP 0.8 vs GPS, HDOP 3.0 of nmea GP* [hhmmss.ss 5dp]"
    )
    assert meta["fix"] == {
        "nmea GPRMC [hhmmss.ss 5dp]": "GPS, HDOP 3.0",
        "nmea GNRMC [hhmmss.ss 4dp]": "GPS, HDOP 0.8",
    }


# --- the simulator: two receivers, one autonomous and noisy, one DGPS -------------------------------

DURATION_S = 600.0
LOST = (200.0, 120.0)  # the DGPS receiver's corrections lost: from 200 s, for 120 s


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    paths, truth, _ = run(tmp_path_factory.mktemp("clean"), None, duration_s=DURATION_S)
    return figures(paths, truth)


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    paths, truth, _ = run(
        tmp_path_factory.mktemp("two"), "poor_gnss,dgps_gnss", duration_s=DURATION_S
    )
    return paths, figures(paths, truth)


def _sources_meta(paths) -> dict:
    from mcap.reader import make_reader

    with open(paths[-1], "rb") as f:
        metas = [m for m in make_reader(f).iter_metadata() if m.name == "sources"]
    return {q: json.loads(v) for q, v in metas[-1].metadata.items()}


def test_the_better_receiver_is_chosen_and_its_track_is_as_good_as_one_clean_receiver(clean, two):
    paths, fig = two
    pos = _sources_meta(paths)["position"]
    assert pos["chosen"] == "nmea GNRMC [hhmmss.ss 4dp]"  # fewer decimals, the better fix
    assert pos["why"] == "the better fix: DGPS, HDOP 0.9 vs GPS, HDOP 2.1 of " + A
    assert pos["sources"]["nmea GPRMC [hhmmss.ss 5dp]"]["used"] <= 1
    assert fig["speed_vs_sog_p95"] < 0.5
    assert fig["speed_vs_sog_p95"] <= 1.1 * clean["speed_vs_sog_p95"]


def test_log_info_says_why_the_receiver_was_chosen(two, capsys):
    assert main(["log", "info", str(two[0][-1])]) == 0
    text = capsys.readouterr().out
    section = text[text.index("sources per quantity") :]
    assert "the better fix: DGPS, HDOP 0.9 vs GPS, HDOP 2.1" in section
    assert "* nmea GNRMC [hhmmss.ss 4dp]" in section and "fix GPS, HDOP 2.1" in section


def test_the_noisy_receiver_chosen_by_the_boat_file_fails_the_speed_check(tmp_path):
    boat = '[sources]\nposition = ["GPRMC"]\n'
    paths, truth, _ = run(tmp_path, "poor_gnss,dgps_gnss", duration_s=300.0, boat_toml=boat)
    pos = _sources_meta(paths)["position"]
    assert pos["chosen"] == "nmea GPRMC [hhmmss.ss 5dp]" and pos["why"].startswith(WHY["priority"])
    assert figures(paths, truth)["speed_vs_sog_p95"] > 1.0


def test_a_receiver_that_loses_its_corrections_hands_over_and_back(tmp_path):
    at, dur = LOST
    paths, _, _ = run(tmp_path, f"poor_gnss,dgps_gnss:at={at:g}:for={dur:g}", duration_s=DURATION_S)
    used = [
        (m.log_time_ns * 1e-9, m.message["source"].split(" ")[1][:2])
        for m in read_messages(paths, "/source/reading")
        if m.message["quantity"] == "position" and m.message["used"]
    ]
    t0 = used[0][0]
    hand = [(t - t0, g) for i, (t, g) in enumerate(used) if i and used[i - 1][1] != g]
    # GN from the first second; GP once GN's median HDOP (6 readings) has been 4.5 for 10 s; GN
    # again once its DGPS has been back for 10 s (its readings come every second)
    assert [g for _, g in hand] == ["GN", "GP", "GN"]
    assert hand[0][0] < 1.5
    assert at + 6.0 + DWELL_S <= hand[1][0] <= at + 6.0 + DWELL_S + 2.0
    assert at + dur + DWELL_S <= hand[2][0] <= at + dur + DWELL_S + 2.0
    assert _sources_meta(paths)["position"]["switches"] == 3


# --- the real captures: what fix they report, and that it changes no choice -------------------------


# per capture: the chosen position source and why (the receiver's fix at the end of the capture:
# the median HDOP of its last 10 s), and by hand from the raw lines: GGA (quality, HDOP) counts,
# RMC/GLL (sentence, mode) counts
CAPTURES = {
    "bundg_zeus_9.log": (
        "nmea GPRMC [hhmmss 4dp]",
        "the only instrument; fix GPS, HDOP 0.6",
        {("1", "0.60"): 137, ("1", "0.70"): 1},
        {("RMC", "A"): 146, ("GLL", "A"): 147},
    ),
    "NeutronDance.log": (
        "nmea GPRMC [hhmmss.sss 4dp]",
        "the only instrument; fix GPS, HDOP 1.0",
        {("1", "1.0"): 181, ("1", "0.9"): 82, ("1", "0.8"): 57, ("1", "1.1"): 2},
        {("RMC", "A"): 1428},
    ),
    "PacCupStartNMEA.txt": (
        "nmea ECRMC [hhmmss 3dp]",
        # its last 20 s: HDOP 5, 20, 8, 8, 4, 8, 9 after 19:53: 2.0 (872 times) or 3.0 (224)
        "the only instrument; fix GPS, HDOP 8.0",
        {
            ("1", "2.0"): 872,
            ("1", "3.0"): 224,
            ("1", "4.0"): 3,
            ("1", "5.0"): 2,
            ("1", "8.0"): 3,
            ("1", "9.0"): 1,
            ("1", "20.0"): 1,
        },
        {("RMC", "A"): 1105, ("GLL", "A"): 1105},
    ),
    "plaka.log": (
        "nmea GPGLL [hhmmss 3dp]",
        "the only instrument; fix DGPS",  # its last GLL: mode D
        {},
        {("GLL", "D"): 7097, ("GLL", "A"): 153},
    ),
}


def _by_hand(path: Path) -> tuple[Counter, Counter]:
    """GGA (quality, HDOP) and RMC/GLL (sentence, mode) of the lines with a good checksum and the
    sentence's number of fields (NeutronDance has two GGA run into other sentences whose checksums
    still hold), by plain string splitting."""
    gga, mode = Counter(), Counter()
    for line in path.read_text("ascii", "replace").splitlines():
        body, star, cs = line.strip()[1:].partition("*")
        hexdigits = len(cs) == 2 and all(c in "0123456789ABCDEFabcdef" for c in cs)
        if not line.startswith("$") or not star or not hexdigits or "$" in body:
            continue
        if reduce(lambda a, c: a ^ ord(c), body, 0) != int(cs, 16):
            continue
        d = body.split(",")
        if d[0][2:] == "GGA" and len(d) == 15:
            gga[(d[6], d[8])] += 1
        elif d[0][2:] == "RMC" and len(d) == 13:
            mode[("RMC", d[12])] += 1
        elif d[0][2:] == "GLL" and len(d) == 8:
            mode[("GLL", d[7])] += 1
    return gga, mode


class MetaSink:
    def __init__(self) -> None:
        self.meta: dict[str, dict[str, str]] = {}

    def write(self, topic, log_time_ns, message) -> None:
        pass

    def metadata(self, name, data) -> None:
        self.meta[name] = dict(data)


@pytest.mark.parametrize("name", sorted(CAPTURES))
def test_the_real_captures_fix_quality(name):
    path = REAL / "nmea" / name
    chosen, why, gga_counts, mode_counts = CAPTURES[name]
    gga, mode = _by_hand(path)
    assert gga == gga_counts
    assert mode == mode_counts
    # forcemap's parser reads the same fields
    parser = NmeaParser()
    mine_gga, mine_mode = Counter(), Counter()
    for line in path.read_bytes().splitlines():
        s = parser.parse(line)
        if s is None or not s.valid or not s.data:
            continue
        if s.type == "GGA":
            mine_gga[(s.data["quality"], s.data["hdop"])] += 1
        elif s.type in ("RMC", "GLL"):
            mine_mode[(s.type, s.data["mode"])] += 1
    assert sum(mine_gga.values()) == sum(gga.values())
    assert {(int(q), float(h)): n for (q, h), n in gga.items()} == dict(mine_gga)
    assert dict(mine_mode) == dict(mode)
    sink = MetaSink()
    import_file(path, sink, "nmea")
    pos = json.loads(sink.meta["sources"]["position"])
    assert (pos["chosen"], pos["why"]) == (chosen, why)
    assert pos["switches"] == 0
    assert np.all([v == why.split("fix ")[1] for v in pos["fix"].values()])
