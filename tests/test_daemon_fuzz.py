"""A minute of fuzzed traffic on each port, delivered fast: no crash, and every rejection counted."""

from __future__ import annotations

import random
import signal
import threading

from tests.test_daemon_support import (
    DaemonProcess,
    PtyPort,
    bridge_frame,
    last_status,
    mavlink_packet,
    nmea_line,
    wait_drained,
)

SEED = 4
BRIDGE_FRAMES = 240  # a minute at 4 Hz
NMEA_LINES = 600  # a minute at 10 Hz
MAVLINK_PACKETS = 3000  # a minute at 50 Hz


def _nonzero(rng: random.Random, n: int, exclude: bytes = b"") -> bytes:
    allowed = [b for b in range(1, 256) if b not in exclude]
    return bytes(rng.choice(allowed) for _ in range(n))


def bridge_stream(rng: random.Random) -> tuple[bytes, int, int]:
    """Frames, some with one byte corrupted, and bursts of junk between frames.

    Each frame has its own 0x00 delimiters and nothing injected contains 0x00, so every damaged
    frame and every junk burst is exactly one rejection.
    """
    out = bytearray()
    good = bad = 0
    for seq in range(BRIDGE_FRAMES):
        frame = bytearray(bridge_frame(seq, 1_000_000 + seq * 250_000))
        if rng.random() < 0.1:
            i = rng.randrange(1, len(frame) - 1)
            frame[i] = rng.choice([b for b in range(1, 256) if b != frame[i]])
            bad += 1
        else:
            good += 1
        out += frame
        if rng.random() < 0.05:
            out += _nonzero(rng, rng.randint(1, 300)) + b"\x00"
            bad += 1
    return bytes(out), good, bad


def nmea_stream(rng: random.Random) -> tuple[bytes, int, int]:
    """Depth sentences with bad checksums, missing checksums, splices, bad fields and binary junk."""
    out = bytearray()
    good = bad = 0
    for i in range(NMEA_LINES):
        line = nmea_line(f"SDDPT,{1 + (i % 70) / 10:.1f},0.3")
        kind = rng.random()
        if kind < 0.03:
            line = line[:-4] + b"00\r\n" if not line.endswith(b"*00\r\n") else line[:-4] + b"01\r\n"
        elif kind < 0.05:
            line = line[: line.index(b"*")] + b"\r\n"
        elif kind < 0.07:
            line = line[:12] + nmea_line("SDDBT,3.3,f,1.0,M,0.5,F")
        elif kind < 0.08:
            line = nmea_line("SDDPT,deep,0.3")
        elif kind < 0.09:
            line = nmea_line("SDDPT,1.0,0.3,5,6")
        elif kind < 0.10:
            line = (
                _nonzero(rng, 1, b"\r\n #$!\t\x0b\x0c")
                + _nonzero(rng, rng.randint(0, 200), b"\r\n")
                + b"\r\n"
            )
        else:
            good += 1
            out += line
            continue
        bad += 1
        out += line
    return bytes(out), good, bad


def mavlink_stream(rng: random.Random) -> tuple[bytes, int, int, int]:
    """Packets, some with a payload byte flipped (bad CRC), and junk without MAVLink magic bytes."""
    out = bytearray()
    good = bad = junk = 0
    for i in range(MAVLINK_PACKETS):
        pkt = bytearray(mavlink_packet(i))
        if rng.random() < 0.05:
            pkt[10 + rng.randrange(len(pkt) - 12)] ^= 1 << rng.randrange(8)
            bad += 1
        else:
            good += 1
        out += pkt
        if rng.random() < 0.01:
            n = rng.randint(1, 100)
            out += _nonzero(rng, n, b"\xfd\xfe")
            junk += n
    return bytes(out), good, bad, junk


def _feed(port: PtyPort, data: bytes, rng: random.Random) -> None:
    i = 0
    while i < len(data):
        n = rng.randint(1, 512)
        port.write(data[i : i + n])
        i += n


def test_fuzzed_ports_no_crash_and_counters_match(tmp_path):
    rng = random.Random(SEED)
    bridge, bridge_good, bridge_bad = bridge_stream(rng)
    nmea, nmea_good, nmea_bad = nmea_stream(rng)
    mav, mav_good, mav_bad, mav_junk = mavlink_stream(rng)
    assert bridge_bad and nmea_bad and mav_bad and mav_junk

    ports = {n: PtyPort(tmp_path / n) for n in ("bridge", "depth", "mavlink")}
    daemon = DaemonProcess(tmp_path / "out", {n: str(p.path) for n, p in ports.items()})
    try:
        daemon.wait_connected(ports)
        writers = [
            threading.Thread(target=_feed, args=(ports[name], data, random.Random(k)))
            for k, (name, data) in enumerate(
                (("bridge", bridge), ("depth", nmea), ("mavlink", mav))
            )
        ]
        for w in writers:
            w.start()
        for w in writers:
            w.join()
        wait_drained(ports.values())
        assert daemon.stop(signal.SIGTERM) == 0
    finally:
        for p in ports.values():
            p.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()

    status = last_status(tmp_path / "out")
    c = status["pipeline"]
    for name in ports:
        assert status["sources"][name]["disconnects"] == 0
    print("bridge", c["bridge"]["frames"], c["bridge"]["rejected"])
    print("nmea", c["nmea"]["accepted"], c["nmea"]["rejected_by_reason"])
    print(
        "mavlink",
        c["mavlink"]["messages"],
        c["mavlink"]["bad_by_reason"],
        c["mavlink"]["junk_bytes"],
    )
    assert c["bridge"]["frames"] == bridge_good
    assert c["bridge"]["rejected"]["total"] == bridge_bad
    assert c["nmea"]["accepted"] == nmea_good
    assert c["nmea"]["rejected"] == nmea_bad
    assert c["mavlink"]["messages"] == mav_good
    assert c["mavlink"]["bad_crc"] == mav_bad
    assert c["mavlink"]["junk_bytes"] == mav_junk
    assert not c["errors"] and not status["errors"]


def test_random_bytes_then_valid_traffic(tmp_path):
    """Pure noise at each port's rate for a minute, then valid traffic is decoded as before."""
    rng = random.Random(SEED + 1)
    noise = {  # bytes in a minute: bridge ~4 Hz x 110 B, NMEA at 4800 baud, MAVLink at 57600 baud
        "bridge": rng.randbytes(30_000),
        "depth": rng.randbytes(30_000),
        "mavlink": rng.randbytes(350_000),
    }
    after = {
        "bridge": b"\x00" + b"".join(bridge_frame(s, 10**9 + s * 250_000) for s in range(10)),
        "depth": b"\r\n" + b"".join(nmea_line(f"SDDPT,{d}.5,0.3") for d in range(10)),
        "mavlink": bytes(300) + b"".join(mavlink_packet(i) for i in range(10)),
    }
    ports = {n: PtyPort(tmp_path / n) for n in noise}
    daemon = DaemonProcess(tmp_path / "out", {n: str(p.path) for n, p in ports.items()})
    try:
        daemon.wait_connected(ports)
        writers = [
            threading.Thread(target=_feed, args=(ports[n], noise[n] + after[n], random.Random(k)))
            for k, n in enumerate(noise)
        ]
        for w in writers:
            w.start()
        for w in writers:
            w.join()
        wait_drained(ports.values())
        assert daemon.stop(signal.SIGTERM) == 0
    finally:
        for p in ports.values():
            p.close()
        if daemon.proc.poll() is None:
            daemon.proc.kill()
    status = last_status(tmp_path / "out")
    c = status["pipeline"]
    assert c["bridge"]["frames"] >= 10
    assert c["nmea"]["accepted_by_type"].get("DPT", 0) >= 10
    assert c["mavlink"]["messages"] >= 10
    assert c["bridge"]["rejected"]["total"] > 0 and c["mavlink"]["junk_bytes"] > 0
    assert not c["errors"] and not status["errors"]
