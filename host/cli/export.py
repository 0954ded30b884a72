"""`forcemap export`: the samples table or the track from one or more MCAP logs."""

from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path

from forcemap.host.convert.export import FORMATS, check_logs, export
from forcemap.host.errors import CliError
from forcemap.host.outputs import check_output

EPILOG = """\
examples:
  forcemap export logs/run-20260601T140000Z.mcap              # -> logs/run-20260601T140000Z.csv
  forcemap export logs/ -o survey.csv                         # every log in the folder, one table
  forcemap export run.mcap --format parquet -o survey.parquet
  forcemap export run.mcap --format kml -o out/               # -> out/run.kml
  forcemap export run.mcap -o - | head                        # CSV on stdout

An existing output is replaced only with --force. `forcemap import` takes the same -o and --force.
"""


def add_output_options(parser: argparse.ArgumentParser, suffix: str) -> None:
    """``-o/--output`` (a file, or a folder for a file named like the input) and ``--force``."""
    parser.add_argument(
        "-o",
        "--output",
        metavar="OUT",
        help=f"output file, or an existing folder for one named like the input ({suffix}); "
        "default: beside the (first) input",
    )
    parser.add_argument("--force", action="store_true", help="replace an existing output file")


def output_for(given: str | None, first_input: str, suffix: str) -> str:
    """The output path: ``given`` (a folder gets the input's name with ``suffix``) or the default."""
    if given is None:
        return str(Path(first_input).with_suffix(suffix))
    if given != "-" and Path(given).is_dir():
        return str(Path(given) / Path(first_input).with_suffix(suffix).name)
    if given.endswith("/"):
        raise CliError(f"the folder {given} does not exist; create it first")
    return given


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = textwrap.fill(
        "Write the samples table (csv, parquet; columns in docs/CONVENTIONS.md) or the boat's track "
        "(geojson, kml) from MCAP logs. Truncated logs are read up to their last complete chunk; "
        "rows repeated across files are kept once.",
        88,
    )
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument(
        "files", nargs="+", metavar="FILE", help="MCAP logs of one survey, or a directory of them"
    )
    parser.add_argument("--format", "-f", choices=FORMATS, default="csv")
    add_output_options(parser, ".csv, .parquet, .geojson or .kml; '-' for stdout, not parquet")


def _expand(paths: list[str]) -> list[str]:
    """A directory stands for the MCAP files in it, in name (= start time) order."""
    out: list[str] = []
    for p in paths:
        if Path(p).is_dir():
            found = sorted(str(f) for f in Path(p).glob("*.mcap"))
            if not found:
                raise CliError(f"no .mcap files in the folder {p}")
            out += found
        elif not Path(p).exists():
            raise CliError(f"{p}: no such file")
        else:
            out.append(p)
    return out


def run(args: argparse.Namespace) -> int:
    files = _expand(args.files)
    check_logs(files)
    out = output_for(args.output, files[0], "." + args.format)
    if out != "-":
        check_output(out, files, args.force)
    summary = export(files, args.format, out)
    if out != "-":
        print(summary, file=sys.stderr)
    return 0
