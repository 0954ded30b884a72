"""`forcemap check LOG|TABLE`: a quality report in USGS QRev's form (docs/QA.md)."""

from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path

from forcemap.host.cli.common import add_boat, add_force, add_json, write_json
from forcemap.host.cli.pipeline_options import add_log_date, add_nmea_checksum
from forcemap.host.errors import CliError

EPILOG = """\
examples:
  forcemap check survey.mcap                  # a log from `run` or `import`
  forcemap check capture.nmea                 # a raw capture or tlog: imported to a temporary log
  forcemap check survey.csv --json -          # a samples table; only the JSON on stdout

Each category (time, position, heading, rate of turn, speed through water, wind, depth, ...) is
green, yellow or red, with the number behind it, the rule (docs/QA.md) and the fix. The exit code is
0 whatever the verdicts.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = textwrap.fill(
        "Grade a log or samples table per category, green, yellow or red, with the number behind "
        "each verdict and the fix: the estimates recorded at import (speed-log gain, rate-of-turn "
        "unit, dead sources, ...) and the checks computed on the samples.",
        88,
    )
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument(
        "file", metavar="LOG_OR_TABLE",
        help="an MCAP log, a samples table (.csv, .parquet), or an NMEA capture or tlog",
    )  # fmt: skip
    add_boat(parser, "calibration for a raw capture (pinned values are used, not estimated)", False)
    add_nmea_checksum(parser)
    add_log_date(parser)
    add_json(parser, "the report")
    add_force(parser)


def run(args: argparse.Namespace) -> int:
    from forcemap.host.convert.importers import ImportFailed
    from forcemap.host.fuse.calibration import ConfigError, load
    from forcemap.host.outputs import check_output
    from forcemap.host.qa.report import check_path, text, to_json
    from forcemap.host.workbench.errors import WorkbenchError

    path = Path(args.file)
    if not path.exists():
        raise CliError(f"{path}: no such file")
    if path.is_dir():
        raise CliError(f"{path} is a folder; give a log (.mcap, NMEA, tlog) or a samples table")
    if args.json not in (None, "-"):
        check_output(args.json, [path], force=args.force)
    try:
        cal = load(args.boat)
        rep = check_path(path, cal, args.nmea_checksum, args.date)
    except (ConfigError, ImportFailed, WorkbenchError) as e:
        raise CliError(str(e)) from None
    out = sys.stderr if args.json == "-" else sys.stdout
    for line in text(rep):
        print(line, file=out)
    write_json(args.json, to_json(rep))
    return 0
