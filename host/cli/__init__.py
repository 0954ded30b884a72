"""The `forcemap` command: a table of subcommands, each imported only when it is run.

Every subcommand lives in its own module, which provides::

    def add_arguments(parser: argparse.ArgumentParser) -> None: ...
    def run(args: argparse.Namespace) -> int: ...

`forcemap --help` lists the table without importing anything heavy, so it stays fast on a Pi.

Exit codes, the same for every command (one place: ``main``):

- 0: done;
- 2: bad input or usage: one line ``forcemap CMD: what is wrong, and what to do`` (raise
  ``forcemap.host.errors.CliError``);
- 1: a bug: the traceback, and a line asking for a report;
- 130: interrupted (Ctrl-C).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import traceback

from forcemap.host.errors import CliError
from forcemap.host.workbench.engine.threads import one_thread_by_default

# name -> (module, one-line summary shown by `forcemap --help`)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": (
        "forcemap.host.cli.demo",
        "run a complete simulated survey: instruments, daemon, MCAP, maps, diagnosis, report",
    ),
    "sim": (
        "forcemap.host.cli.sim",
        "start a simulated river or lake with its instruments behind virtual serial ports",
    ),
    "run": (
        "forcemap.host.cli.run",
        "the acquisition daemon: read bridge, depth sounder and autopilot, log to MCAP",
    ),
    "replay": (
        "forcemap.host.cli.replay",
        "stream a finished MCAP log to Foxglove as if live, with the maps as they grew (--live)",
    ),
    "live-layout": (
        "forcemap.host.cli.live_layout",
        "write the Foxglove layout for the live view (map, plots, health, alerts)",
    ),
    "bridge": (
        "forcemap.host.cli.bridge",
        "flash the MicroPython bridge firmware, or monitor its frames live",
    ),
    "log": ("forcemap.host.cli.log", "inspect (`log info`) or repair (`log recover`) an MCAP log"),
    "export": (
        "forcemap.host.cli.export",
        "write the samples table (csv, parquet) or the track (geojson, kml) from an MCAP log",
    ),
    "import": (
        "forcemap.host.cli.import_",
        "read an existing NMEA 0183 capture or MAVLink tlog into an MCAP log",
    ),
    "check": (
        "forcemap.host.cli.check",
        "grade a log or samples table per category (QRev's form): green, yellow, red, number, fix",
    ),
    "fit": (
        "forcemap.host.cli.fit",
        "fit a map model to a samples table and report its cross-validated error",
    ),
    "diagnose": (
        "forcemap.host.cli.diagnose",
        "find which physical effect the current model is missing",
    ),
    "season": (
        "forcemap.host.cli.season",
        "many surveys of one river: static depth, the current's shape x discharge, map half-life",
    ),
    "history": (
        "forcemap.host.cli.history",
        "show every fit of a survey with its CV error, as a table and a plot",
    ),
    "grid": (
        "forcemap.host.cli.grid",
        "write the survey's maps for GIS: GeoTIFF, NetCDF (CF) or GeoJSON contours, in its UTM zone",
    ),
    "report": (
        "forcemap.host.cli.report",
        "write a self-contained HTML report of a survey's maps and diagnosis",
    ),
    "plan": (
        "forcemap.host.cli.plan",
        "predict a waypoint mission through the mapped current and adjust it to hold its lines",
    ),
}

EPILOG = """\
typical session:
  forcemap demo                                   # everything, simulated, in a few minutes
  forcemap sim --scenario river --ports /tmp/ports --speed 50 &
  forcemap run --bridge /tmp/ports/bridge --depth /tmp/ports/depth \\
               --mavlink /tmp/ports/mavlink,115200 --clock sim:/tmp/ports/clock -o logs/
  forcemap export logs/run-*.mcap -o survey.csv
  forcemap fit survey.csv --target current_speed
  forcemap diagnose survey.csv --target current_speed
  forcemap run ... --live                         # watch it in Foxglove: ws://127.0.0.1:8765

Units and conventions: docs/CONVENTIONS.md. The options' grammar (-o/--output, --force, --json PATH|-,
--boat, --quiet, durations as 30s/20m/3h): docs/CLI.md. `forcemap COMMAND --help` explains each command.
"""


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="forcemap",
        description="Measure wind, current and depth from a small surface vehicle and turn them into maps.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, summary) in COMMANDS.items():
        p = sub.add_parser(name, help=summary, description=summary)
        if name == command:
            importlib.import_module(module).add_arguments(p)
    return parser


def main(argv: list[str] | None = None) -> int:
    # before any subcommand's module loads numpy (importing this package loads none)
    one_thread_by_default()
    argv = sys.argv[1:] if argv is None else argv
    command = next((a for a in argv if not a.startswith("-")), None)
    if command not in COMMANDS:
        command = None
    parser = build_parser(command)
    args = parser.parse_args(argv)
    try:
        if args.command is None:
            parser.print_help()
            return 0
        module = importlib.import_module(COMMANDS[args.command][0])
        return int(module.run(args) or 0)
    except CliError as exc:
        print(f"forcemap {args.command}: {exc}", file=sys.stderr)
        return exc.code
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`forcemap log info F | head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except Exception:
        traceback.print_exc()
        print(
            f"forcemap {args.command}: this is a bug in forcemap, not in your data; please report it "
            "with the command line and the traceback above",
            file=sys.stderr,
        )
        return 1
