"""`forcemap export`: the samples table or the track from one or more MCAP logs."""

from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path

from forcemap.host.cli.common import add_deprecated, add_output, output_for
from forcemap.host.convert.export import FORMATS, check_logs, export
from forcemap.host.errors import CliError
from forcemap.host.outputs import check_output

EPILOG = """\
examples:
  forcemap export logs/run-20260601T140000Z.mcap              # -> logs/run-20260601T140000Z.csv
  forcemap export logs/ -o survey.csv                         # every log in the folder, one table
  forcemap export run.mcap -o survey.parquet                  # the format from the suffix
  forcemap export run.mcap --to kml -o out/                   # -> out/run.kml
  forcemap export run.mcap -o - | head                        # CSV on stdout

The format is the output's suffix (.csv, .parquet, .geojson, .kml), or --to where there is no file name
to read it from (a folder, stdout, the default beside the input); csv when neither says.
An existing output is replaced only with --force. `forcemap import` takes the same -o and --force.
"""


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
    add_output(
        parser,
        "output file (.csv, .parquet, .geojson or .kml), an existing folder for one named like the "
        "first input, or '-' for stdout (not parquet); default: beside the first input",
        metavar="OUT",
    )
    parser.add_argument(
        "--to",
        choices=FORMATS,
        default=None,
        help="the output's format, where its name does not say (default: from the suffix, else csv)",
    )
    add_deprecated(parser, ("--format", "-f"), "--to FORMAT, or an output suffix", "to")


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


def output_format(given: str | None, to: str | None) -> str:
    """The format: ``--to``, else the output's suffix, else csv; a suffix that disagrees is an error."""
    suffix = Path(given).suffix.lower().lstrip(".") if given not in (None, "-") else ""
    if given not in (None, "-") and Path(given).is_dir():
        suffix = ""
    if suffix and suffix not in FORMATS and to is None:
        raise CliError(
            f"cannot tell the format from {given}: name it .csv, .parquet, .geojson or .kml, "
            "or give --to"
        )
    if to and suffix in FORMATS and suffix != to:
        raise CliError(f"--to {to} but the output {given} is named .{suffix}; make them agree")
    return to or (suffix if suffix in FORMATS else "csv")


def run(args: argparse.Namespace) -> int:
    files = _expand(args.files)
    check_logs(files)
    given = args.output
    if given not in (None, "-") and not Path(given).is_dir():
        check_output(given, files, args.force)  # an input named as the output: refused first
    fmt = output_format(given, args.to)
    out = output_for(given, files[0], "." + fmt)
    if out != "-":
        check_output(out, files, args.force)
    notes: list[str] = []
    summary = export(files, fmt, out, notes)
    for note in notes:  # a truncated log: how much of it was read, always on stderr
        print(f"note: {note}", file=sys.stderr)
    if out != "-":
        print(summary, file=sys.stderr)
    return 0
