# Run by tests/test_protocol_golden.py under the real MicroPython unix port:
#   micropython golden_check.py LIB VECTORS_JSON
# Prints one line per vector: "ok NAME" or "FAIL NAME reason".
import json
import sys

sys.path.insert(0, sys.argv[1])
from binascii import hexlify, unhexlify  # noqa: E402

from forcemap.protocol import wire  # noqa: E402

with open(sys.argv[2]) as f:
    vectors = json.load(f)

for v in vectors:
    payload = unhexlify(v["payload"])
    wire_bytes = unhexlify(v["wire"])
    enc = wire.encode(v["msg_type"], v["boot_id"], v["seq"], v["t_us"], payload, v["flags"])
    if enc != wire_bytes:
        print("FAIL", v["name"], "encode", str(hexlify(enc), "ascii"))
        continue
    dec = wire.StreamDecoder()
    frames = dec.feed(wire_bytes)
    if len(frames) != 1:
        print("FAIL", v["name"], "decoded", len(frames), "frames", dec.rejects)
        continue
    fr = frames[0]
    got = (fr.msg_type, fr.flags, fr.boot_id, fr.seq, fr.t_us, fr.payload)
    want = (v["msg_type"], v["flags"], v["boot_id"], v["seq"], v["t_us"], payload)
    print("ok" if got == want else "FAIL", v["name"])
