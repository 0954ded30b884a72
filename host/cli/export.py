"""`forcemap export`: the samples table or the track from one or more MCAP logs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from forcemap.host.export import FORMATS, export


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Write the samples table (csv, parquet; columns in docs/CONVENTIONS.md) or the boat's track "
        "(geojson, kml) from MCAP logs. Truncated logs are read up to their last complete chunk."
    )
    parser.add_argument(
        "files", nargs="+", metavar="FILE", help="MCAP logs of one survey, or a directory of them"
    )
    parser.add_argument("--format", "-f", choices=FORMATS, default="csv")
    parser.add_argument(
        "-o",
        "--output",
        metavar="OUT",
        help="output file; '-' for stdout (not parquet); default: first FILE with the format's suffix",
    )


def _expand(paths: list[str]) -> list[str]:
    """A directory stands for the MCAP files in it, in name (= start time) order."""
    out: list[str] = []
    for p in paths:
        out += sorted(str(f) for f in Path(p).glob("*.mcap")) if Path(p).is_dir() else [p]
    return out


def run(args: argparse.Namespace) -> int:
    files = _expand(args.files)
    if not files:
        print(f"forcemap export: no .mcap files in {' '.join(args.files)}", file=sys.stderr)
        return 1
    out = args.output or str(Path(files[0]).with_suffix("." + args.format))
    try:
        summary = export(files, args.format, out)
    except (OSError, ValueError) as exc:
        print(f"forcemap export: {exc}", file=sys.stderr)
        return 1
    if out != "-":
        print(summary, file=sys.stderr)
    return 0
