"""The `forcemap` command: a table of subcommands, each imported only when it is run.

Every subcommand lives in its own module, which provides::

    def add_arguments(parser: argparse.ArgumentParser) -> None: ...
    def run(args: argparse.Namespace) -> int: ...

`forcemap --help` lists the table without importing anything heavy, so it stays fast on a Pi.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

# name -> (module, one-line summary shown by `forcemap --help`)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": (
        "host.demo",
        "run a complete simulated survey: instruments, daemon, MCAP, maps, diagnosis, report",
    ),
    "sim": (
        "sim_devices.cli",
        "start a simulated river or lake with its instruments behind virtual serial ports",
    ),
    "run": (
        "host.run_cli",
        "the acquisition daemon: read bridge, depth sounder and autopilot, log to MCAP",
    ),
    "bridge": (
        "host.bridge_cli",
        "flash the MicroPython bridge firmware, or monitor its frames live",
    ),
    "log": ("host.log_cli", "inspect (`log info`) or repair (`log recover`) an MCAP log"),
    "export": (
        "host.export_cli",
        "write the samples table (csv, parquet) or the track (geojson, kml) from an MCAP log",
    ),
    "import": (
        "host.import_cli",
        "read an existing NMEA 0183 capture or MAVLink tlog into an MCAP log",
    ),
    "fit": (
        "host.workbench.cli_fit",
        "fit a map model to a samples table and report its cross-validated error",
    ),
    "diagnose": (
        "host.workbench.cli_diagnose",
        "find which physical effect the current model is missing",
    ),
    "history": (
        "host.workbench.cli_history",
        "show every fit of a survey with its CV error, as a table and a plot",
    ),
    "report": (
        "host.workbench.cli_report",
        "write a self-contained HTML report of a survey's maps and diagnosis",
    ),
}

EPILOG = """\
typical session:
  forcemap demo                                   # everything, simulated, in a few minutes
  forcemap sim --scenario river --ports /tmp/ports --speed 50 &
  forcemap run --bridge /tmp/ports/bridge --depth /tmp/ports/depth \\
               --mavlink /tmp/ports/mavlink,115200 --out logs/
  forcemap export logs/run-*.mcap --format csv -o survey.csv
  forcemap fit survey.csv --target current_speed
  forcemap diagnose survey.csv --target current_speed

Units and conventions: docs/CONVENTIONS.md. `forcemap COMMAND --help` explains each command.
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
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`forcemap log info F | head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
