"""NMEA: line splitting over any chunking, strict checks with counted reasons, SI extraction."""

from __future__ import annotations

import random

import pytest
from forcemap.host.decode.nmea import KNOT, LineSplitter, NmeaParser, depth_below_surface


def cs(body: str) -> str:
    c = 0
    for ch in body.encode():
        c ^= ch
    return f"${body}*{c:02X}"


def test_splitter_any_chunking_gives_the_same_lines():
    text = b"".join(
        cs(f"SDDBT,{i}.0,f,{i * 0.3048:.2f},M,,F").encode() + b"\r\n" for i in range(200)
    )
    want = LineSplitter().feed(text)
    assert len(want) == 200
    rng = random.Random(3)
    for _ in range(20):
        sp, got, i = LineSplitter(), [], 0
        while i < len(text):
            n = rng.randint(1, 40)
            got += sp.feed(text[i : i + n])
            i += n
        assert got + sp.flush() == want


def test_splitter_bounds_a_line_without_end():
    sp = LineSplitter(max_line=100)
    out = sp.feed(b"x" * 250)
    assert out == [b"x" * 100]
    assert sp.feed(b"\n$A*00\n") == [b"$A*00"]


def test_good_sentences_and_values():
    p = NmeaParser()
    s = p.parse(cs("SDDBT,8.46,f,2.58,M,1.41,F").encode())
    assert s.valid and s.type == "DBT" and s.talker == "SD"
    assert s.data["depth_m"] == pytest.approx(2.58)
    s = p.parse(cs("SDDPT,2.58,0.30,100.0"))
    assert s.data == {"depth_m": 2.58, "offset_m": 0.30}
    assert p.parse(cs("SDMTW,18.5,C")).data["water_temp"] == 18.5
    r = p.parse(cs("GPRMC,190315.000,A,3503.8851,N,07658.0729,W,5.0,27.56,120816,15.0,E,A"))
    assert r.valid
    assert r.data["lat"] == pytest.approx(35 + 3.8851 / 60)
    assert r.data["lon"] == pytest.approx(-(76 + 58.0729 / 60))
    assert r.data["sog"] == pytest.approx(5 * KNOT)
    assert r.data["cog"] == 27.56 and r.data["variation"] == 15.0
    assert r.data["utc"] == pytest.approx(1471028595.0)  # 2016-08-12 19:03:15 UTC
    v = p.parse(cs("IIVWR,079,L,21.0,N,10.8,M,038.9,K"))
    assert v.data["angle"] == -79.0 and v.data["speed"] == pytest.approx(21.0 * KNOT)
    m = p.parse(cs("WIMWV,293.0,R,5.23,N,A"))
    assert (
        m.data["angle"] == -67.0
        and m.data["reference"] == "R"
        and m.data["speed"] == pytest.approx(5.23 * KNOT)
    )
    h = p.parse(cs("SDHDG,229.8,,,1.3,E"))
    assert h.data == {"heading_mag": 229.8, "deviation": None, "variation": 1.3}
    assert p.parse(cs("IIHDT,,T")).data == {"heading": None}  # empty but well-formed (plaka.log)
    assert sum(p.accepted.values()) == 8 and not p.rejected


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        # real spliced lines whose checksums match by chance (NeutronDance.log, PacCupStartNMEA.txt)
        ("$SDDBT,9.18,f,2.80,M,T,,M,3.02,N,5.58,K*5D", "field_count"),
        ("$SBT,8.59,f,2.62,M,1.43,F*32", "parse_error"),
        ("$SDDPT,2.56GPRMC*00", "bad_checksum"),
        ("$SDDPT,2.56,0.0", "no_checksum"),
        ("$SDDPT,2.56,0.0*5", "no_checksum"),
        ("$SDDPT,2.56,0.0*ZZ", "no_checksum"),
        ("SDDPT,2.56,0.0*5B", "no_start"),
        ("$SDVLW,$SDVLW,,N,,N*59", "spliced"),
        ("!!VER:1.9,UID:MEGA", "spliced"),
        ("Initializing..", "no_start"),
        (cs("SDDBT,abc,f,2.80,M,1.5,F"), "bad_field"),
        (cs("SDDBT,9.1,x,2.80,M,1.5,F"), "bad_field"),
        (cs("GPRMC,250000,A,3503.8851,N,07658.0729,W,0.27,27.56,120816,,,A"), "bad_field"),
        (cs("GPRMC,190315,A,3503.8851,N,07658.0729,W,0.27,27.56,121316,,,A"), "bad_field"),
        (cs("SDMTW,18.5"), "field_count"),
        ("$" + "A" * 200 + "*00", "too_long"),
    ],
)
def test_rejections_are_counted_by_reason(line, reason):
    p = NmeaParser()
    s = p.parse(line)
    assert not s.valid and s.reason == reason
    assert p.rejected == {reason: 1} and not p.accepted


def test_not_ascii_and_comments():
    p = NmeaParser()
    assert p.parse(b"$SD\xffDBT*00").reason == "not_ascii"
    assert p.parse(b"# Zeus\xc2\xb2 capture") is None
    assert p.parse(b"   ") is None
    assert p.lines == 1


def test_other_valid_sentences_are_accepted_unchecked():
    p = NmeaParser()
    assert p.parse("!AIVDM,1,1,,A,15Ml7W?P?wG@5BRE`tw>4?vP0L16,0*28").valid
    assert p.parse(cs("GPGLC,9960,,,,,,,,,,,,")).valid  # a type pynmea2 does not know
    assert p.parse(cs("PGRMT,GPS17x Software Version 2.30,,,,,,,")).valid
    assert p.accepted == {"other": 3}


def test_random_garbage_never_raises_and_is_all_counted():
    rng = random.Random(7)
    p, sp = NmeaParser(), LineSplitter()
    n = 0
    for _ in range(300):
        chunk = bytes(rng.randrange(256) for _ in range(rng.randint(1, 200)))
        for line in sp.feed(chunk):
            s = p.parse(line)
            n += s is not None
    assert p.lines == n == sum(p.rejected.values()) + sum(p.accepted.values())
    assert sum(p.accepted.values()) == 0


def test_depth_below_surface():
    p = NmeaParser()
    assert depth_below_surface(p.parse(cs("SDDPT,2.5,0.4,")), 0.3) == pytest.approx(
        2.9
    )  # own offset
    assert depth_below_surface(p.parse(cs("SDDPT,2.5,-1.2,")), 0.3) == pytest.approx(
        2.8
    )  # keel: calibration
    assert depth_below_surface(p.parse(cs("SDDPT,2.5,,")), 0.3) == pytest.approx(2.8)
    assert depth_below_surface(p.parse(cs("SDDBT,8.2,f,2.5,M,1.4,F")), 0.3) == pytest.approx(2.8)
    assert depth_below_surface(p.parse(cs("SDDBT,10.0,f,,M,,F")), 0.0) == pytest.approx(3.048)
    assert depth_below_surface(p.parse(cs("SDDBT,,f,,M,,F")), 0.0) is None
    assert depth_below_surface(p.parse(cs("SDMTW,18.5,C")), 0.0) is None


def _read(parser: NmeaParser, lines: list, times: int = 1) -> tuple[list, tuple]:
    """Each line parsed, `times` over, and the parser's counts."""
    out = [parser.parse(ln) for _ in range(times) for ln in lines]
    names = ("accepted", "rejected", "variants", "variant_addresses", "lines")
    return out, tuple(getattr(parser, n) for n in names)


def test_a_line_parsed_once_reads_and_counts_as_parsed_anew():
    """Within `parsed_once` (an import's passes over one capture) a parser gives each line as a parser
    without it does: equal sentences, new objects (a consumer may change one), the same counts by type,
    reason and checksum variant, whichever parser saw the line first and however often."""
    from forcemap.host.decode.nmea import parsed_once
    from forcemap.host.decode.nmea_checksum import xor

    lines = [cs("SDDPT,2.56,0.30"), cs("SDDBT,8.46,f,2.58,M,1.41,F"), cs("PGRMT,GPS17x,,,,,,,")]
    lines += ["$SDDPT,2.56GPRMC*00", "Initializing..", "   ", "# a comment"]
    lines.append(f"$IIHDG,229.8,,,1.3,E*{xor('IIHDG'):02X}")  # a bus's checksum over the address only
    lines += [ln.encode() for ln in lines] + [bytearray(b"\xff$SDDPT*00")]
    for mode in ("strict", "lenient"):
        once, twice = _read(NmeaParser(mode), lines), _read(NmeaParser(mode), lines, 2)
        assert once[1][2] and once[1][0] and once[1][1]  # a variant, accepted and rejected lines
        with parsed_once():
            first = _read(NmeaParser(mode), lines)
            again = _read(NmeaParser(mode), lines, 2)
        assert first == once and again == twice, mode
        got = [s for s in first[0] + again[0] if s is not None]
        assert len({id(s) for s in got}) == len(got)  # every sentence its own object
