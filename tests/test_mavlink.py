"""MAVLink: bulk decoding in any chunking, bad packets counted by sender and id, SI conversions."""

from __future__ import annotations

import math
import random

import pytest
from forcemap.host.decode.mavlink import MavlinkDecoder, is_vehicle, raw_dict, to_si, vehicle_of
from pymavlink.dialects.v20 import ardupilotmega as mavlink


class _Buf:
    def __init__(self):
        self.out = bytearray()

    def write(self, b):
        self.out += b


def encoder(sysid=1, compid=1):
    buf = _Buf()
    return mavlink.MAVLink(buf, srcSystem=sysid, srcComponent=compid), buf


def stream(n=200):
    m, buf = encoder()
    for i in range(n):
        m.attitude_send(i * 100, 0.01, -0.02, math.radians(-90.0), 0.0, 0.0, math.radians(5.0))
        m.global_position_int_send(
            i * 100, 339_900_000, -810_500_000, 1000, 500, 120, -250, 0, 27000
        )
        if i % 10 == 0:
            m.heartbeat_send(10, 3, 0, 0, 4)
            m.system_time_send(1_750_000_000_000_000 + i * 100_000, i * 100)
    return bytes(buf.out)


def test_any_chunking_gives_the_same_messages():
    data = stream()
    whole = [x.to_dict() for x in MavlinkDecoder().feed(data)]
    assert len(whole) == 440
    rng = random.Random(1)
    dec, got, i = MavlinkDecoder(), [], 0
    while i < len(data):
        n = rng.choice([1, 2, 7, 50, 300, 4096])
        got += [x.to_dict() for x in dec.feed(data[i : i + n])]
        i += n
    assert got == whole
    assert dec.counters()["messages"] == 440 and dec.counters()["bad_crc"] == 0


def test_bad_crc_counted_by_sender_and_msgid():
    m, buf = encoder(sysid=7, compid=194)
    m.distance_sensor_send(1, 20, 700, 123, 0, 0, 0, 0)
    pkt = bytearray(buf.out)
    pkt[-3] ^= 0xFF  # a payload byte: the CRC no longer matches
    good = stream(5)
    dec = MavlinkDecoder()
    msgs = dec.feed(good + bytes(pkt) + good + bytes(pkt))
    assert dec.bad_crc == {(7, 194, 132): 2}
    assert dec.counters()["bad_crc_by_sender_msgid"] == {"7/194/132": 2}
    assert len(msgs) == 2 * len(MavlinkDecoder().feed(good))


def test_garbage_never_raises():
    rng = random.Random(5)
    dec = MavlinkDecoder()
    for _ in range(200):
        dec.feed(bytes(rng.randrange(256) for _ in range(rng.randint(1, 300))))
    dec.feed(b"\xfd" * 1000 + b"\xfe" * 1000)
    good = stream(3)
    assert len(dec.feed(b"\x00" * 300 + good)) >= 1
    assert dec.counters()["junk_bytes"] > 0


def test_si_conversions():
    msgs = MavlinkDecoder().feed(stream(1))
    by = {x.get_type(): x for x in msgs}
    g = to_si(by["GLOBAL_POSITION_INT"])
    assert g["lat"] == pytest.approx(33.99) and g["lon"] == pytest.approx(-81.05)
    assert g["v_north"] == pytest.approx(1.2) and g["v_east"] == pytest.approx(-2.5)
    assert g["alt"] == pytest.approx(1.0) and g["heading"] == pytest.approx(270.0)
    a = to_si(by["ATTITUDE"])
    assert a["heading"] == pytest.approx(270.0) and a["yaw_rate"] == pytest.approx(5.0)
    assert to_si(by["SYSTEM_TIME"])["time_unix_usec"] == 1_750_000_000_000_000
    m, buf = encoder()
    m.gps_raw_int_send(1, 3, 1, 2, 3, 65535, 65535, 65535, 65535, 255)
    m.vfr_hud_send(0.0, 1.5, 90, 37, 0.0, 0.0)
    r = MavlinkDecoder().feed(bytes(buf.out))
    gps, hud = to_si(r[0]), to_si(r[1])
    assert (
        gps["eph"] is None
        and gps["sog"] is None
        and gps["cog"] is None
        and gps["satellites"] is None
    )
    assert hud["throttle"] == 37.0 and hud["groundspeed"] == pytest.approx(1.5)
    assert raw_dict(r[1])["_src"] == [1, 1]


def test_vehicle_is_the_autopilot_not_the_gcs():
    m, buf = encoder(sysid=255, compid=190)
    m.heartbeat_send(6, 8, 0, 0, 0)  # a GCS
    m2, buf2 = encoder(sysid=1, compid=1)
    m2.heartbeat_send(10, 3, 0, 0, 4)
    gcs, veh = MavlinkDecoder().feed(bytes(buf.out) + bytes(buf2.out))
    assert vehicle_of(gcs) is None and vehicle_of(veh) == (1, 1)
    assert is_vehicle(veh, (1, 1)) and not is_vehicle(gcs, (1, 1)) and not is_vehicle(gcs, None)


def test_raw_dicts_are_json_safe():
    import json

    m, buf = encoder()
    m.vfr_hud_send(float("nan"), 1.0, 3, 4, 5.0, 6.0)
    m.statustext_send(4, b"hello")
    m.vfr_hud_send(1.0, float("inf"), 3, 4, 5.0, 6.0)
    a, b, c = (raw_dict(x) for x in MavlinkDecoder().feed(bytes(buf.out)))
    assert a["airspeed"] is None and c["groundspeed"] is None and c["airspeed"] == 1.0
    assert b["text"] == "hello"
    json.dumps([a, b, c], allow_nan=False)
