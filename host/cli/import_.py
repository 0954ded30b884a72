"""`forcemap import`: an NMEA 0183 capture or a MAVLink tlog into an MCAP log with the daemon's topics."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "file",
        metavar="FILE",
        help="NMEA 0183 capture (text), MAVLink telemetry log (.tlog) or DataFlash log (.BIN)",
    )
    parser.add_argument(
        "--out", default=".", metavar="DIR", help="directory for the MCAP file (default: .)"
    )
    parser.add_argument(
        "--format",
        choices=("nmea", "tlog", "dataflash"),
        default=None,
        help="input format (default: from the name and the first bytes)",
    )
    parser.add_argument(
        "--config", default=None, metavar="BOAT_TOML", help="calibration (default: built-in)"
    )
    parser.add_argument(
        "--sync",
        choices=("interpolate", "approximate"),
        default=None,
        help="boat-state matching (default: the config's sync.mode)",
    )


def _out_path(out: Path, stem: str) -> Path:
    import time

    return out / f"{stem}-{time.strftime('%Y%m%dT%H%M%SZ', time.gmtime())}.mcap"


_UNITS = {"nmea": "lines", "tlog": "packets", "dataflash": "records"}


def summary(res: Any) -> list[str]:
    """Human-readable lines about an ImportResult."""
    c = res.counters
    out = [f"{res.path}: {res.records} {_UNITS[res.format]} ({res.format})"]
    if res.format == "nmea":
        n = c["depth"]
        out.append(
            f"  NMEA: {n['accepted']} accepted {dict(sorted(n['accepted_by_type'].items()))}"
        )
        out.append(
            f"        {n['rejected']} rejected {dict(sorted(n['rejected_by_reason'].items()))}"
        )
    elif res.format == "tlog":
        m = c["mavlink"]
        out.append(
            f"  MAVLink: {m['messages']} messages, {m['bad_crc']} bad CRC, {m['junk_bytes']} junk bytes"
        )
        for key, n in sorted(m["bad_crc_by_sender_msgid"].items(), key=lambda kv: -kv[1])[:5]:
            out.append(f"           bad CRC from sysid/compid/msgid {key}: {n}")
    if c.get("last_fix"):
        f = c["last_fix"]
        out.append(f"  last fix: {f['lat']:.6f}, {f['lon']:.6f}")
    out.extend("  " + note for note in res.notes)
    return out


def run(args: argparse.Namespace) -> int:
    from forcemap.host.calibration import ConfigError, load
    from forcemap.host.importers import ImportFailed, check_importable, import_to_mcap
    from forcemap.host.outputs import check_output

    path = Path(args.file)
    try:
        cal = load(args.config)
        if not path.is_file():
            raise ImportFailed(f"{path}: no such file")
        fmt = check_importable(path, args.format)
    except (ConfigError, ImportFailed) as e:
        print(f"forcemap import: {e}", file=sys.stderr)
        return 2
    Path(args.out).mkdir(parents=True, exist_ok=True)
    out = check_output(_out_path(Path(args.out), path.stem), [path])
    try:
        res = import_to_mcap(path, out, fmt, cal, args.sync)
    except ImportFailed as e:
        print(f"forcemap import: {e}", file=sys.stderr)
        return 2
    for line in summary(res):
        print(line)
    print(f"  -> {out}")
    return 0
