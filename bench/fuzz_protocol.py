"""Fuzz benchmark of the bridge protocol's streaming decoder.

Feeds >= 10^6 mutated frames (bit flips, byte substitutions, deletions, insertions, truncations,
garbage bursts) through one StreamDecoder in random-sized chunks, and prints:
- decoded frames per second, as a ratio against the baseline of the same decoder on clean frames;
- the rejection counts by reason;
- false accepts: decoded frames that differ from the frame that was sent (must be 0).

    python bench/fuzz_protocol.py [--n 1000000] [--seed 1]
"""

from __future__ import annotations

import argparse
import random
import time

from forcemap.protocol import wire


def base_frames(rng: random.Random, n: int, boot: int) -> list[tuple[tuple, bytes]]:
    out = []
    for seq in range(n):
        kind = rng.choice(
            (wire.SAMPLE, wire.SAMPLE, wire.SAMPLE, wire.STATUS, wire.HELLO, wire.LOG)
        )
        if kind == wire.SAMPLE:
            payload = wire.pack_sample(
                rng.randrange(65536),
                [
                    (rng.randrange(wire.COUNT_MOD), rng.randrange(2**40), rng.randrange(2**20))
                    for _ in range(5)
                ],
            )
        elif kind == wire.STATUS:
            payload = wire.pack_status([rng.randrange(2**32) for _ in range(6)])
        elif kind == wire.HELLO:
            payload = wire.pack_hello(
                (1, 0, 0), 1, 250_000, 30, 1.5, (21.6,) * 4, "nano_rp2040", "anemo=D2"
            )
        else:
            payload = b"log %d" % seq
        key = (kind, 0, boot, seq, seq * 250_000, payload)
        out.append((key, wire.encode(kind, boot, seq, seq * 250_000, payload)))
    return out


MUTATED_BOOT = 0xB007
CLEAN_BOOT = 0xC1EA


def mutate(rng: random.Random, w: bytes) -> bytes:
    b = bytearray(w)
    for _ in range(rng.randint(1, 4)):
        if not b:
            break
        op = rng.randrange(6)
        i = rng.randrange(len(b))
        if op == 0:
            b[i] ^= 1 << rng.randrange(8)
        elif op == 1:
            b[i] = rng.randrange(256)
        elif op == 2:
            del b[i]
        elif op == 3:
            b[i:i] = rng.randbytes(rng.randint(1, 8))
        elif op == 4:
            del b[i:]
        else:
            b[i:i] = rng.randbytes(rng.randint(20, 300))  # a burst of line noise
    return bytes(b)


def run(stream_parts: list[bytes], rng: random.Random) -> tuple[wire.StreamDecoder, list, float]:
    dec = wire.StreamDecoder()
    data = b"".join(stream_parts)
    out = []
    t0 = time.perf_counter()
    i = 0
    while i < len(data):
        j = i + rng.randint(1, 512)
        out += dec.feed(data[i:j])
        i = j
    return dec, out, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--n", type=int, default=1_000_000, help="mutated inputs (default 10^6)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rng = random.Random(args.seed)

    n_base = min(args.n, 200_000)
    frames = base_frames(rng, n_base, MUTATED_BOOT)
    clean = base_frames(
        rng, n_base, CLEAN_BOOT
    )  # interleaved unmutated, to measure collateral loss
    sent = {k[2:4]: k for k, _ in frames + clean}

    # baseline: the same decoder on clean frames
    dec, out, t_clean = run([w for _, w in frames], rng)
    assert len(out) == n_base and dec.rejected() == 0
    clean_rate = n_base / t_clean

    mutated = []
    pristine = 0
    for k in range(args.n):
        key, w = frames[k % n_base]
        m = mutate(rng, w)
        pristine += m == w
        mutated.append(m)
        if k % 3 == 0:
            mutated.append(clean[k % n_base][1])
    n_good_sent = (args.n + 2) // 3
    dec, out, t_fuzz = run(mutated, rng)
    false_accepts = 0
    clean_decoded = 0
    for f in out:
        key = sent.get((f.boot_id, f.seq))
        if key is None or (f.msg_type, f.flags, f.boot_id, f.seq, f.t_us, f.payload) != key:
            false_accepts += 1
        clean_decoded += f.boot_id == CLEAN_BOOT
    inputs = len(mutated)
    mb = sum(map(len, mutated)) / 1e6
    print(
        f"fuzz_protocol: {args.n:,} mutated frames + {n_good_sent:,} clean ones interleaved ({mb:.1f} MB)"
    )
    print(f"  baseline  clean decode           : {clean_rate:12,.0f} frames/s")
    print(
        f"  fuzzed    stream decode          : {inputs / t_fuzz:12,.0f} inputs/s  ({inputs / t_fuzz / clean_rate:.2f}x baseline)"
    )
    print(f"            decoded frames          : {len(out):,} ({len(out) / t_fuzz:,.0f} frames/s)")
    print(f"            clean frames sent/decoded: {n_good_sent:,} / {clean_decoded:,}")
    print(
        f"            mutated frames decoded  : {len(out) - clean_decoded:,} (mutation left the frame decodable, e.g. a deleted delimiter; {pristine:,} byte-identical)"
    )
    print(f"  rejections by reason             : {dec.rejects}")
    print(f"  false accepts                    : {false_accepts}")
    print(f"  clean frames lost to neighbours  : {n_good_sent - clean_decoded}")
    if false_accepts or clean_decoded != n_good_sent:
        raise SystemExit("FAILED: false accepts or collateral loss")


if __name__ == "__main__":
    main()
