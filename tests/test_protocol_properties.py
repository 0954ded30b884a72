"""Property tests of the streaming decoder: chunking, garbage, corruption and resynchronization.

Together these run 100,000 generated cases (hypothesis), as the foundation issue asks of CI.
"""

from __future__ import annotations

from forcemap.protocol import wire
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

COMMON = dict(deadline=None, suppress_health_check=list(HealthCheck), database=None)

u32 = st.integers(0, 2**32 - 1)
u64 = st.integers(0, 2**64 - 1)


@st.composite
def frames(draw):
    """A valid frame of any known type, as (Frame fields tuple, wire bytes)."""
    msg_type = draw(st.sampled_from(sorted(wire.TYPE_NAMES)))
    # any bytes of the right size are a well-formed SAMPLE or STATUS payload
    if msg_type == wire.SAMPLE:
        payload = draw(st.binary(min_size=wire.SAMPLE_SIZE, max_size=wire.SAMPLE_SIZE))
    elif msg_type == wire.STATUS:
        payload = draw(st.binary(min_size=wire.STATUS_SIZE, max_size=wire.STATUS_SIZE))
    elif msg_type == wire.HELLO:
        payload = wire.pack_hello(
            (1, 0, draw(st.integers(0, 255))),
            draw(st.integers(0, 5)),
            draw(st.integers(1000, 10**7)),
            30,
            1.5,
            (20.0, 21.0, 22.0, 23.0),
            draw(st.text(max_size=20)),
            draw(st.text(max_size=40)),
        )
    else:
        payload = draw(st.text(max_size=120)).encode()[: wire.MAX_PAYLOAD]
    key = (msg_type, draw(st.integers(0, 1)), draw(u32), draw(u32), draw(u64), payload)
    return key, wire.encode(msg_type, key[2], key[3], key[4], payload, key[1])


def key_of(f: wire.Frame):
    return (f.msg_type, f.flags, f.boot_id, f.seq, f.t_us, f.payload)


def feed_in_chunks(data: bytes, cuts: list[int]):
    dec = wire.StreamDecoder()
    out = []
    prev = 0
    for c in sorted(set(c % (len(data) + 1) for c in cuts)) + [len(data)]:
        out += dec.feed(data[prev:c])
        prev = c
    return dec, out


garbage = st.binary(max_size=40)


@settings(max_examples=40_000, **COMMON)
@given(
    st.lists(st.tuples(frames(), garbage), max_size=6), st.lists(st.integers(0, 10**6), max_size=8)
)
def test_any_chunking_with_garbage_decodes_exactly_the_frames(items, cuts):
    stream = b"".join(g + w for (_, w), g in items)
    _, out = feed_in_chunks(stream, cuts)
    assert [key_of(f) for f in out] == [k for (k, _), _ in items]


@st.composite
def corrupted(draw, w: bytes):
    """``w`` damaged by bit flips, substitutions, deletions, insertions or truncation."""
    b = bytearray(w)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["flip", "sub", "del", "ins", "trunc"]))
        if not b:
            break
        i = draw(st.integers(0, len(b) - 1))
        if kind == "flip":
            b[i] ^= 1 << draw(st.integers(0, 7))
        elif kind == "sub":
            b[i] = draw(st.integers(0, 255))
        elif kind == "del":
            del b[i]
        elif kind == "ins":
            b[i:i] = draw(st.binary(min_size=1, max_size=8))
        else:
            del b[i:]
    return bytes(b)


@st.composite
def frame_and_damage(draw):
    key, w = draw(frames())
    return key, w, draw(corrupted(w))


@settings(max_examples=30_000, **COMMON)
@given(frame_and_damage(), st.lists(st.integers(0, 400), max_size=4))
def test_corrupting_a_frame_never_yields_a_wrong_frame(fd, cuts):
    key, _, bad = fd
    dec, out = feed_in_chunks(bad + b"\x00", cuts)
    for f in out:
        assert key_of(f) == key  # only the original survives, never something else
    if not out and bad.strip(b"\x00"):
        assert dec.rejected() >= 1  # a frame lost to damage is counted, never silent


@settings(max_examples=30_000, **COMMON)
@given(frames(), frame_and_damage(), frames(), st.lists(st.integers(0, 10**4), max_size=6))
def test_corrupting_one_frame_never_costs_its_neighbours(a, b, c, cuts):
    (ka, wa), (kb, _, bad), (kc, wc) = a, b, c
    _, out = feed_in_chunks(wa + bad + wc, cuts)
    keys = [key_of(f) for f in out]
    assert keys[0] == ka and keys[-1] == kc
    assert all(k == kb for k in keys[1:-1])
