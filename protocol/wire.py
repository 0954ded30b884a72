"""The bridge's wire format: COBS-framed, CRC-32-checked frames. Encoder and streaming decoder.

This one module runs unchanged on the board (MicroPython) and on the host (CPython): no typing,
no dataclasses, only ``struct`` and ``binascii.crc32``. The byte layout is in ``protocol/SPEC.md``.

On the wire every frame is ``0x00 | COBS(header | payload | crc32) | 0x00``.
"""

import struct
from binascii import crc32

MAGIC = 0xF5
VERSION_MAJOR = 1
VERSION_MINOR = 0
VERSION = (VERSION_MAJOR << 4) | VERSION_MINOR

SAMPLE = 1
HELLO = 2
STATUS = 3
LOG = 4
TYPE_NAMES = {SAMPLE: "SAMPLE", HELLO: "HELLO", STATUS: "STATUS", LOG: "LOG"}

# flags
FLAG_DROPPED_BEFORE = 0x01  # the device dropped at least one frame since the previous one it sent

# magic, version, type, flags, boot_id, seq, t_us, payload_len
HEADER = "<BBBBIIQH"
HEADER_SIZE = 22
CRC_SIZE = 4
MIN_BODY = HEADER_SIZE + CRC_SIZE
MAX_PAYLOAD = 240
MAX_BODY = HEADER_SIZE + MAX_PAYLOAD + CRC_SIZE
MAX_WIRE = MAX_BODY + MAX_BODY // 254 + 2

# Cumulative pulse counts wrap at 2**30 so the board's ISR keeps them as small ints (no allocation).
COUNT_BITS = 30
COUNT_MOD = 1 << COUNT_BITS
SEQ_MOD = 1 << 32
N_WHEELS = 4

# SAMPLE payload: vane raw ADC, then 5 channels (anemometer, wheel1..wheel4) of
# (cumulative count, device time of the last accepted edge in us, period between the last two edges in us)
SAMPLE_FMT = "<H" + "IQI" * (1 + N_WHEELS)
SAMPLE_SIZE = 82
# STATUS payload: frames_sent, write_timeouts, frames_dropped, mem_free, bounce_rejects, loop_overruns
STATUS_FMT = "<IIIIII"
STATUS_SIZE = 24
STATUS_FIELDS = (
    "frames_sent",
    "write_timeouts",
    "frames_dropped",
    "mem_free",
    "bounce_rejects",
    "loop_overruns",
)
# HELLO fixed part: fw major, minor, patch, reset_cause, sample_period_us, ticks_period_bits,
# count_bits, anemometer Hz per m/s, wheel pulses per metre x4; then board and pin map as
# length-prefixed UTF-8 strings.
HELLO_FMT = "<BBBBIBBfffff"
HELLO_SIZE = 30

REJECT_REASONS = ("cobs", "length", "crc", "version", "unknown_type")


def cobs_encode(data):
    """COBS-encode ``data``: the result contains no zero byte."""
    out = bytearray()
    start = 0
    n = len(data)
    while True:
        end = data.find(b"\x00", start, start + 254) if start < n else -1
        if end < 0:
            block_end = min(start + 254, n)
            out.append(block_end - start + 1)
            out += data[start:block_end]
            if block_end >= n:
                break
            start = block_end
        else:
            out.append(end - start + 1)
            out += data[start:end]
            start = end + 1
            if start == n:
                out.append(1)
                break
    return bytes(out)


def cobs_decode(data):
    """Decode one COBS block (no delimiters). Returns the bytes, or None if the block is malformed."""
    out = bytearray()
    i = 0
    n = len(data)
    while i < n:
        code = data[i]
        if code == 0:
            return None
        j = i + code
        if j > n:
            return None
        out += data[i + 1 : j]
        i = j
        if code != 255 and i < n:
            out.append(0)
    return bytes(out)


def build_body(msg_type, boot_id, seq, t_us, payload, flags=0):
    """Header, payload and CRC-32: the bytes that COBS wraps."""
    if len(payload) > MAX_PAYLOAD:
        raise ValueError("payload longer than %d bytes" % MAX_PAYLOAD)
    body = struct.pack(
        HEADER, MAGIC, VERSION, msg_type, flags, boot_id, seq & 0xFFFFFFFF, t_us, len(payload)
    ) + bytes(payload)
    return body + struct.pack("<I", crc32(body) & 0xFFFFFFFF)


def encode(msg_type, boot_id, seq, t_us, payload, flags=0):
    """One complete frame as it goes on the wire, with its leading and trailing delimiters."""
    return b"\x00" + cobs_encode(build_body(msg_type, boot_id, seq, t_us, payload, flags)) + b"\x00"


def pack_sample(vane_raw, channels):
    """SAMPLE payload. ``channels`` is 5 (count, last_edge_us, period_us) triples: anemometer, wheels 1-4."""
    a, b, c, d, e = channels
    return struct.pack(
        SAMPLE_FMT,
        vane_raw,
        a[0],
        a[1],
        a[2],
        b[0],
        b[1],
        b[2],
        c[0],
        c[1],
        c[2],
        d[0],
        d[1],
        d[2],
        e[0],
        e[1],
        e[2],
    )


def pack_status(values):
    """STATUS payload from a sequence of the six counters in ``STATUS_FIELDS`` order."""
    return struct.pack(STATUS_FMT, *values)


def pack_hello(
    fw, reset_cause, sample_period_us, ticks_bits, anemo_hz_per_mps, wheel_ppm, board, pins
):
    """HELLO payload. ``fw`` is (major, minor, patch); ``wheel_ppm`` four pulses-per-metre values."""
    b = board.encode()
    p = pins.encode()
    return (
        struct.pack(
            HELLO_FMT,
            fw[0],
            fw[1],
            fw[2],
            reset_cause,
            sample_period_us,
            ticks_bits,
            COUNT_BITS,
            anemo_hz_per_mps,
            wheel_ppm[0],
            wheel_ppm[1],
            wheel_ppm[2],
            wheel_ppm[3],
        )
        + bytes([len(b)])
        + b
        + bytes([len(p)])
        + p
    )


def _text(b):
    """UTF-8 text that never raises: undecodable bytes become '?'."""
    try:
        return str(bytes(b), "utf-8")
    except UnicodeError:
        return "".join([chr(c) if c < 128 else "?" for c in b])


class Frame:
    """A decoded frame. ``fields`` holds the message's fields by name (see ``decode_payload``)."""

    def __init__(self, msg_type, flags, boot_id, seq, t_us, payload, fields):
        self.msg_type = msg_type
        self.flags = flags
        self.boot_id = boot_id
        self.seq = seq
        self.t_us = t_us
        self.payload = payload
        self.fields = fields

    def __eq__(self, other):
        return (
            isinstance(other, Frame)
            and self.msg_type == other.msg_type
            and self.flags == other.flags
            and self.boot_id == other.boot_id
            and self.seq == other.seq
            and self.t_us == other.t_us
            and self.payload == other.payload
        )

    def __repr__(self):
        return "Frame(%s boot=%08x seq=%d t_us=%d %r)" % (
            TYPE_NAMES.get(self.msg_type, self.msg_type),
            self.boot_id,
            self.seq,
            self.t_us,
            self.fields,
        )


def decode_payload(msg_type, payload):
    """Fields of a known message type as a dict, or None if the payload is too short.

    A payload longer than the known layout comes from a newer minor version: the known prefix is
    decoded and the rest ignored.
    """
    n = len(payload)
    if msg_type == SAMPLE:
        if n < SAMPLE_SIZE:
            return None
        v = struct.unpack_from(SAMPLE_FMT, payload, 0)
        return {
            "vane_raw": v[0],
            "anemo": (v[1], v[2], v[3]),
            "wheels": (
                (v[4], v[5], v[6]),
                (v[7], v[8], v[9]),
                (v[10], v[11], v[12]),
                (v[13], v[14], v[15]),
            ),
        }
    if msg_type == STATUS:
        if n < STATUS_SIZE:
            return None
        v = struct.unpack_from(STATUS_FMT, payload, 0)
        d = {}
        for i in range(len(STATUS_FIELDS)):
            d[STATUS_FIELDS[i]] = v[i]
        return d
    if msg_type == HELLO:
        if n < HELLO_SIZE + 2:
            return None
        v = struct.unpack_from(HELLO_FMT, payload, 0)
        i = HELLO_SIZE
        lb = payload[i]
        board = payload[i + 1 : i + 1 + lb]
        i += 1 + lb
        if i >= n:
            return None
        lp = payload[i]
        pins = payload[i + 1 : i + 1 + lp]
        if len(board) != lb or len(pins) != lp:
            return None
        return {
            "fw_version": "%d.%d.%d" % (v[0], v[1], v[2]),
            "reset_cause": v[3],
            "sample_period_us": v[4],
            "ticks_period_bits": v[5],
            "count_bits": v[6],
            "anemo_hz_per_mps": v[7],
            "wheel_pulses_per_m": (v[8], v[9], v[10], v[11]),
            "board": _text(board),
            "pins": _text(pins),
        }
    if msg_type == LOG:
        return {"text": _text(payload)}
    return None


def decode_body(body, counts):
    """Check and decode one un-COBSed frame body. Returns a Frame, or None after counting the reason."""
    n = len(body)
    if n < MIN_BODY:
        counts["length"] += 1
        return None
    if crc32(body[: n - CRC_SIZE]) & 0xFFFFFFFF != struct.unpack_from("<I", body, n - CRC_SIZE)[0]:
        counts["crc"] += 1
        return None
    magic, version, msg_type, flags, boot_id, seq, t_us, plen = struct.unpack_from(HEADER, body, 0)
    if magic != MAGIC or (version >> 4) != VERSION_MAJOR:
        counts["version"] += 1
        return None
    if plen != n - MIN_BODY:
        counts["length"] += 1
        return None
    payload = bytes(body[HEADER_SIZE : n - CRC_SIZE])
    if msg_type not in TYPE_NAMES:
        counts["unknown_type"] += 1
        return None
    fields = decode_payload(msg_type, payload)
    if fields is None:
        counts["length"] += 1
        return None
    return Frame(msg_type, flags, boot_id, seq, t_us, payload, fields)


def decode_frame(wire):
    """Decode one frame given with or without its delimiters. Returns a Frame or None."""
    counts = new_counts()
    block = bytes(wire).strip(b"\x00")
    body = cobs_decode(block)
    if body is None:
        return None
    return decode_body(body, counts)


def new_counts():
    d = {}
    for r in REJECT_REASONS:
        d[r] = 0
    return d


class StreamDecoder:
    """Turns bytes in any chunking into frames. Never raises on bad input.

    Every rejected frame is counted by reason in ``rejects``. A frame ends at the next 0x00, so a
    damaged frame costs only itself and the decoder resynchronizes at the next delimiter.
    """

    def __init__(self):
        self._buf = bytearray()
        self._discarding = False
        self.rejects = new_counts()
        self.frames = 0
        self.bytes_in = 0

    def feed(self, data):
        """Add bytes; return the list of frames they completed."""
        self.bytes_in += len(data)
        out = []
        start = 0
        n = len(data)
        while start < n:
            z = data.find(b"\x00", start)
            if z < 0:
                self._append(data[start:])
                break
            self._append(data[start:z])
            self._end_block(out)
            start = z + 1
        return out

    def _append(self, chunk):
        if self._discarding or not chunk:
            return
        if len(self._buf) + len(chunk) > MAX_WIRE:
            self._buf = bytearray()
            self._discarding = True
            self.rejects["length"] += 1
            return
        self._buf += chunk

    def _end_block(self, out):
        if self._discarding:
            self._discarding = False
            return
        if not self._buf:
            return
        body = cobs_decode(self._buf)
        self._buf = bytearray()
        if body is None:
            self.rejects["cobs"] += 1
            return
        frame = decode_body(body, self.rejects)
        if frame is not None:
            self.frames += 1
            out.append(frame)

    def rejected(self):
        """Total frames rejected for any reason."""
        total = 0
        for r in REJECT_REASONS:
            total += self.rejects[r]
        return total


def count_delta(earlier, later):
    """Pulses between two cumulative counts of the same boot, across the 2**30 wrap."""
    return (later - earlier) % COUNT_MOD


def seq_delta(earlier, later):
    """Frames between two sequence numbers of the same boot, across the 2**32 wrap."""
    return (later - earlier) % SEQ_MOD
