"""Variants of a real NMEA log as other boats and loggers write it, to run every command on (bench/RESULTS.md,
"Logs as other boats write them"):

    python bench/log_variants.py DIR [--log LOG]
    bench/sweep_real_logs.sh SWEEPDIR DIR/*.nmea

LOG defaults to Irene's day on the Flensburg fjord, 2013-07-31 (tests/data/real/nmea/irene/).

Each variant changes one thing a log we have not seen may do differently, every sentence's checksum made
right first (the Flensburg day's are a variant's, which `--nmea-checksum lenient` reads):

- `talkers`: the talker each instrument would have on a mixed bus (GN, HC, SD, WI, VW, YX, EC), not II;
- `no_gll` / `no_rmc`: the position from RMC only, or from GLL only (no date, no speed or course over ground);
- `no_heading`: no HDG (a boat without a compass on the bus);
- `prefixed`: a logger's time stamp before each sentence;
- `tagblock`: an NMEA 4 TAG block before each sentence;
- `crlf_garbage`: CR LF line ends, and three bytes of noise after every 97th sentence.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from forcemap.host.decode.nmea_checksum import xor

REAL = Path(__file__).resolve().parents[1] / "tests/data/real/nmea"
LOG = REAL / "irene" / "irene_2013-07-31_flensburg_checksums.nmea"
TALKERS = {
    "RMC": "GN", "GLL": "GN", "HDG": "HC", "DPT": "SD", "MWV": "WI", "VHW": "VW", "VWR": "WI",
    "MTW": "YX", "VLW": "VW", "RMB": "EC",
}  # fmt: skip


def with_checksum(line: str) -> str:
    """The sentence with its checksum computed over the whole sentence, as the standard has it."""
    if not line.startswith("$"):
        return line
    body = line[1:].split("*")[0]
    return f"${body}*{xor(body):02X}"


def retalked(line: str) -> str:
    """The sentence with the talker its instrument would have on a mixed bus."""
    kind = line[3:6]
    if line.startswith("$II") and kind in TALKERS:
        return with_checksum("$" + TALKERS[kind] + line[3:])
    return line


def tag_block(i: int, line: str) -> str:
    """The sentence behind an NMEA 4 TAG block with a source and a UNIX time."""
    body = f"s:logger,c:{1375264800 + i // 10}"
    return f"\\{body}*{xor(body):02X}\\{line}"


def variants(lines: list[str]) -> dict[str, list[str]]:
    """Every variant's lines."""
    return {
        "talkers": [retalked(ln) for ln in lines],
        "no_gll": [ln for ln in lines if ln[3:6] != "GLL"],
        "no_rmc": [ln for ln in lines if ln[3:6] != "RMC"],
        "no_heading": [ln for ln in lines if ln[3:6] != "HDG"],
        "prefixed": [f"2013-07-31 {i:08d} {ln}" for i, ln in enumerate(lines)],
        "tagblock": [tag_block(i, ln) for i, ln in enumerate(lines)],
        "crlf_garbage": [
            ln + ("\x00\xff\xfe" if i % 97 == 0 else "") for i, ln in enumerate(lines)
        ],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dir", type=Path)
    p.add_argument("--log", type=Path, default=LOG)
    a = p.parse_args()
    lines = [with_checksum(ln) for ln in a.log.read_text(encoding="latin-1").splitlines()]
    a.dir.mkdir(parents=True, exist_ok=True)
    stem = a.log.name.split(".")[0]
    for name, out in variants(lines).items():
        end = "\r\n" if name == "crlf_garbage" else "\n"
        path = a.dir / f"{stem}_{name}.nmea"
        path.write_bytes((end.join(out) + end).encode("latin-1"))
        print(path)


if __name__ == "__main__":
    main()
