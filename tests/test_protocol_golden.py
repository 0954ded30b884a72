"""The golden vectors in protocol/SPEC.md, checked in both directions under CPython and MicroPython."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from forcemap.protocol import wire

from tests import tools
from tests.protocol_vectors import golden_vectors

ROOT = Path(__file__).resolve().parents[1]
VECTORS = golden_vectors()


def test_spec_has_a_vector_for_every_message_type():
    assert {v["msg_type"] for v in VECTORS} == set(wire.TYPE_NAMES)


@pytest.mark.parametrize("v", VECTORS, ids=[v["name"] for v in VECTORS])
def test_encode_matches_spec(v):
    payload = bytes.fromhex(v["payload"])
    assert (
        wire.encode(v["msg_type"], v["boot_id"], v["seq"], v["t_us"], payload, v["flags"]).hex()
        == v["wire"]
    )


@pytest.mark.parametrize("v", VECTORS, ids=[v["name"] for v in VECTORS])
def test_decode_matches_spec(v):
    dec = wire.StreamDecoder()
    frames = dec.feed(bytes.fromhex(v["wire"]))
    assert len(frames) == 1, dec.rejects
    f = frames[0]
    assert (f.msg_type, f.flags, f.boot_id, f.seq, f.t_us) == (
        v["msg_type"],
        v["flags"],
        v["boot_id"],
        v["seq"],
        v["t_us"],
    )
    assert f.payload.hex() == v["payload"]


def test_sample_vector_fields():
    v = next(v for v in VECTORS if v["name"] == "sample")
    f = wire.decode_frame(bytes.fromhex(v["wire"]))
    assert f.fields["vane_raw"] == 50294
    assert f.fields["anemo"] == (1234, 249120, 100020)
    assert f.fields["wheels"][2] == (1073741823, 1073741824123, 12)
    assert f.fields["wheels"][3] == (5, 2**64 - 1, 2**32 - 1)


def test_hello_vector_fields():
    v = next(v for v in VECTORS if v["name"] == "hello")
    f = wire.decode_frame(bytes.fromhex(v["wire"]))
    assert f.fields["board"] == "nano_rp2040"
    assert f.fields["sample_period_us"] == 250_000
    assert f.fields["count_bits"] == wire.COUNT_BITS
    assert f.fields["anemo_hz_per_mps"] == pytest.approx(1.5)
    assert f.fields["pins"].startswith("anemo=D2")


def test_cobs_matches_reference_implementation():
    from cobs import cobs  # the reference implementation, in the test extras

    for n in (0, 1, 253, 254, 255, 508, 509):
        for data in (bytes(n), bytes(range(1, 256))[:n] * 1, (b"\x11" * n)):
            assert wire.cobs_encode(data) == cobs.encode(data)
            assert wire.cobs_decode(wire.cobs_encode(data)) == data


def test_golden_vectors_under_real_micropython(tmp_path):
    exe = tools.micropython()
    vec_file = tmp_path / "vectors.json"
    vec_file.write_text(json.dumps(VECTORS))
    out = subprocess.run(
        [
            exe,
            str(ROOT / "tests" / "upy" / "golden_check.py"),
            str(tools.board_lib()),
            str(vec_file),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr
    lines = out.stdout.split("\n")
    assert sorted(line for line in lines if line) == sorted("ok " + v["name"] for v in VECTORS), (
        out.stdout
    )
