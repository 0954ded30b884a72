"""One source per quantity (issue 20): names and fingerprints, priorities, fallback and return,
two compasses never interleaved, corrupt MAVLink frames counted without a topic."""

from __future__ import annotations

import pytest
from forcemap.host.fuse import calibration
from forcemap.host.fuse.calibration import ConfigError
from forcemap.host.fuse.pipeline import ListSink, Pipeline
from forcemap.host.fuse.sources import (
    WHY,
    SourceSelector,
    default_rank,
    nmea_fingerprint,
    source_name,
)
from forcemap.sim_devices.nmea_sounder import sentence
from pymavlink.dialects.v20 import ardupilotmega as mavlink2


def test_a_position_sentence_carries_its_receivers_fingerprint():
    a = "$GPRMC,123519.00,A,4807.03812,N,01131.00000,E,5.0,84.4,230394,,,A*6A"
    b = "$GPRMC,123519,A,4807.038,N,01131.000,E,5.0,84.4,230394,,,A*6A"
    gll = "$GPGLL,4807.0381,N,01131.0000,E,123519.000,A,A*00"
    assert nmea_fingerprint(a, "RMC") == "hhmmss.ss 5dp"
    assert nmea_fingerprint(b, "RMC") == "hhmmss 3dp"
    assert nmea_fingerprint(gll, "GLL") == "hhmmss.sss 4dp"
    assert source_name("nmea", "GP", "RMC", "hhmmss 3dp") == "nmea GPRMC [hhmmss 3dp]"


def test_the_default_order_prefers_precision_instruments_and_true_heading():
    pos = sorted(
        ["nmea IIRMC [hhmmss 3dp]", "nmea GPRMC [hhmmss 3dp]", "nmea GPRMC [hhmmss.ss 5dp]"],
        key=lambda n: default_rank("position", n),
    )
    assert pos == [
        "nmea GPRMC [hhmmss.ss 5dp]",
        "nmea GPRMC [hhmmss 3dp]",
        "nmea IIRMC [hhmmss 3dp]",
    ]
    hdg = sorted(
        ["nmea HCHDM", "nmea HEHDT", "nmea VWVHW"], key=lambda n: default_rank("heading", n)
    )
    assert hdg == ["nmea HEHDT", "nmea HCHDM", "nmea VWVHW"]
    assert default_rank("position", "mavlink GLOBAL_POSITION_INT") < default_rank(
        "position", "nmea GPRMC [hhmmss.ss 5dp]"
    )


def test_fallback_when_the_preferred_source_is_silent_and_return_after():
    sel = SourceSelector(timeouts={"heading": 3.0})
    good, other = "nmea HEHDT", "nmea HCHDM"
    used = []
    for k in range(60):
        t = k * 0.5
        if not 10 <= t < 20:  # the preferred compass is silent for 10 s
            used.append((t, good, sel.accept("heading", good, t, (1.0,))))
        used.append((t, other, sel.accept("heading", other, t, (2.0,))))
    taken = {(round(t, 1), n) for t, n, ok in used if ok}
    assert all(n == good for t, n in taken if t < 10 or t >= 20)
    # the other one only after the timeout, and never once the preferred is back
    assert {t for t, n in taken if n == other} == {x * 0.5 for x in range(26, 40)}
    assert sel.switches["heading"] == 2
    assert sel.reason("heading") == WHY["quality"]


def test_the_boat_file_sets_priorities_and_timeouts():
    cal = calibration.loads(
        '[sources]\nposition = ["IIRMC"]\nheading = "HDT"\ntimeout_s = { heading = 2.5 }\n'
    )
    assert cal.source_priorities == {"position": ["IIRMC"], "heading": ["HDT"]}
    assert cal.source_timeouts == {"heading": 2.5}
    sel = SourceSelector(cal.source_priorities, cal.source_timeouts)
    assert sel.accept("position", "nmea GPRMC [hhmmss.ss 5dp]", 0.0, (0, 0, 0, 0))
    assert sel.accept("position", "nmea IIRMC [hhmmss 3dp]", 0.5, (0, 0, 0, 0))
    assert not sel.accept("position", "nmea GPRMC [hhmmss.ss 5dp]", 1.0, (0, 0, 0, 0))
    assert sel.reason("position") == WHY["priority"]
    for bad, key in (
        ("[sources]\nposition = 3\n", "sources.position"),
        ("[sources]\nspeed = ['x']\n", "sources.speed"),
        ("[sources]\ntimeout_s = -1\n", "sources.timeout_s"),
    ):
        with pytest.raises(ConfigError, match=key):
            calibration.loads(bad)


def _line(talker: str, kind: str, fields: tuple[str, ...]) -> bytes:
    return (sentence(talker, kind, fields) + "\r\n").encode()


def test_two_compasses_are_never_interleaved():
    """A fluxgate at 5 Hz and a damped compass at 1 Hz, 10 deg apart: 'whichever came last' made a
    yaw rate of 10 deg per 0.2 s = 50 deg/s; one source at a time keeps it near zero."""
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    t0 = 1_780_000_000.0
    for k in range(300):
        t = t0 + k * 0.2
        ns = int(t * 1e9)
        data = _line("HC", "HDG", (f"{100.0 + 0.3 * (k % 3):.1f}", "", "", "0.0", "E"))
        if k % 5 == 0:
            data += _line("II", "HDT", ("110.0", "T"))
            sec = t0 + k * 0.2
            hms = f"{int(sec % 86400 // 3600):02d}{int(sec % 3600 // 60):02d}{sec % 60:05.2f}"
            fields = (hms, "A", "4700.00000", "N", "00800.00000", "E", "0.0", "0.0", "010626")
            data += _line("GP", "RMC", fields + ("", "", "A"))
            data += _line("VW", "VHW", ("", "T", "", "M", "2.0", "N", "", "K"))
        pipe.feed("nmea", ns, ns, data)
    pipe.close()
    rows = sink.topic("/samples")
    assert len(rows) > 40
    yaw = [abs(r["yaw_rate"]) for r in rows if r["yaw_rate"] is not None]
    assert max(yaw) < 5.0
    assert all(abs(r["heading"] - 100.3) < 1.0 for r in rows if r["heading"] is not None)
    meta = dict([m for m in sink.meta if m[0] == "sources"][-1][1])
    assert '"chosen": "nmea HCHDG +variation"' in meta["heading"]
    readings = sink.topic("/source/reading")
    assert {r["source"] for r in readings if r["quantity"] == "heading"} == {
        "nmea HCHDG +variation",
        "nmea IIHDT",
    }
    assert not any(r["used"] for r in readings if r["source"] == "nmea IIHDT")


def test_a_corrupt_mavlink_frame_is_counted_and_makes_no_topic():
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    good = bytes(mavlink2.MAVLink_heartbeat_message(10, 3, 0, 0, 4, 3).pack(mav))
    bad = bytearray(good)
    bad[7:10] = (13107200).to_bytes(3, "little")  # a message id no dialect has
    sink = ListSink()
    pipe = Pipeline(sink=sink)
    pipe.feed("mavlink", 10**9, 10**9, good + bytes(bad) + good)
    pipe.close()
    assert {t for t, _, _ in sink.messages if t.startswith("/mavlink/")} == {"/mavlink/HEARTBEAT"}
    assert pipe.counters()["mavlink"]["unknown_messages"] == 1
