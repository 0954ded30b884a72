"""Each rejection reason of the streaming decoder, the versioning rule and the wrap helpers."""

from __future__ import annotations

import struct
from binascii import crc32

import pytest
from forcemap.protocol import wire

SAMPLE = wire.pack_sample(1000, [(5, 10, 20)] * 5)


def frame_with(body: bytes) -> bytes:
    """Wrap an arbitrary body (header+payload) with a correct CRC, as a frame on the wire."""
    body = body + struct.pack("<I", crc32(body))
    return b"\x00" + wire.cobs_encode(body) + b"\x00"


def header(magic=wire.MAGIC, version=wire.VERSION, msg_type=wire.SAMPLE, plen=None, payload=SAMPLE):
    plen = len(payload) if plen is None else plen
    return struct.pack(wire.HEADER, magic, version, msg_type, 0, 7, 1, 250_000, plen) + payload


def decode_all(data: bytes):
    dec = wire.StreamDecoder()
    return dec, dec.feed(data)


def test_good_frame_decodes():
    dec, out = decode_all(frame_with(header()))
    assert len(out) == 1 and dec.rejected() == 0


@pytest.mark.parametrize(
    "data, reason",
    [
        (frame_with(header(version=0x20)), "version"),  # unknown major
        (frame_with(header(magic=0xAA)), "version"),
        (frame_with(header(msg_type=99)), "unknown_type"),
        (frame_with(header(plen=81)), "length"),  # payload_len disagrees with the body
        (frame_with(header(payload=SAMPLE[:40])), "length"),  # SAMPLE shorter than its layout
        (b"\x00\x04\x01\x02\x03\x00", "length"),  # body shorter than header + CRC
        (b"\x00\x09\x01\x02\x00", "cobs"),  # code byte points past the block
        (b"\x00" + b"\x01" * 600 + b"\x00", "length"),  # runaway block without a delimiter
    ],
)
def test_each_rejection_is_counted_by_reason(data, reason):
    dec, out = decode_all(data)
    assert out == []
    assert dec.rejects[reason] == 1
    assert dec.rejected() == 1


def test_crc_rejection():
    good = wire.encode(wire.SAMPLE, 7, 1, 250_000, SAMPLE)
    body = bytearray(wire.cobs_decode(good.strip(b"\x00")))
    body[30] ^= 0x40
    dec, out = decode_all(b"\x00" + wire.cobs_encode(bytes(body)) + b"\x00")
    assert out == [] and dec.rejects["crc"] == 1


def test_newer_minor_version_with_longer_payload_is_read():
    longer = SAMPLE + b"\x01\x02\x03\x04"  # a field a future minor version appends
    dec, out = decode_all(frame_with(header(version=(wire.VERSION_MAJOR << 4) | 3, payload=longer)))
    assert dec.rejected() == 0
    assert out[0].fields["vane_raw"] == 1000 and out[0].fields["anemo"] == (5, 10, 20)


def test_unknown_type_does_not_stop_the_stream():
    good = wire.encode(wire.STATUS, 7, 2, 1, wire.pack_status([1, 2, 3, 4, 5, 6]))
    dec, out = decode_all(frame_with(header(msg_type=42)) + good)
    assert [f.msg_type for f in out] == [wire.STATUS]
    assert dec.rejects["unknown_type"] == 1


def test_resynchronizes_after_garbage_without_delimiters():
    good = wire.encode(wire.SAMPLE, 7, 3, 500_000, SAMPLE)
    dec, out = decode_all(
        b"\x7f\xff\x13noise" + good[1:] + good
    )  # first frame lost its leading 0x00
    assert len(out) == 1 and out[0].seq == 3
    assert dec.rejected() == 1


def test_encoder_refuses_oversize_payload():
    with pytest.raises(ValueError):
        wire.encode(wire.LOG, 1, 1, 1, b"x" * (wire.MAX_PAYLOAD + 1))


def test_count_and_seq_deltas_wrap():
    assert wire.count_delta(wire.COUNT_MOD - 3, 4) == 7
    assert wire.count_delta(10, 10) == 0
    assert wire.seq_delta(2**32 - 1, 1) == 2


def test_undecodable_text_never_raises():
    dec, out = decode_all(wire.encode(wire.LOG, 1, 1, 1, b"ok \xe2\x82"))
    assert out[0].fields["text"] == "ok ??"
