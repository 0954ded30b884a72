"""Shared plumbing of the workbench commands: the table argument, outputs checked up front, JSON, notes.

Errors are not handled here: a ``CliError`` (``WorkbenchError`` is one) reaches ``forcemap.host.cli.main``,
which prints it on one line and exits 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from forcemap.host.errors import CliError
from forcemap.host.outputs import atomic_write, check_output


def add_table(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "table",
        type=Path,
        help="samples table: .csv, .parquet, or an .mcap log from `forcemap run`",
    )


def add_workspace_options(parser: argparse.ArgumentParser, output: bool = True) -> None:
    """--reset-history, and --force when the command writes a file the user names."""
    parser.add_argument(
        "--reset-history",
        action="store_true",
        help="move a corrupt TABLE.forcemap/history.json aside (kept as history.json.bak-N) and "
        "start a new history",
    )
    if output:
        parser.add_argument("--force", action="store_true", help="replace an existing output file")


def teach(parser: argparse.ArgumentParser, epilog: str) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = epilog


def prepare_workspace(args: argparse.Namespace, create: bool = False) -> Path:
    """Check the table and the workspace before any heavy work (creating it only with `create`:
    a command that fails leaves no empty folder behind); apply --reset-history."""
    from forcemap.host.workbench.workspace import (
        check_workspace,
        load_history,
        reset_history,
        workspace_dir,
    )

    table = Path(args.table)
    if not table.exists():
        raise CliError(f"{table}: no such file")
    if table.is_dir():
        raise CliError(f"{table} is a folder; give a samples table (.csv, .parquet or .mcap)")
    ws = workspace_dir(table, create=create)
    check_workspace(ws)
    if getattr(args, "reset_history", False):
        backup = reset_history(ws)
        if backup is not None:
            print(f"note: the old history is kept as {backup}; a new one starts", file=sys.stderr)
    load_history(ws)  # a corrupt history stops the command here, before the work
    return ws


def check_json_output(args: argparse.Namespace) -> None:
    """--json OUT must be writable (and new, or --force) before the work starts."""
    if args.json is not None and str(args.json) != "-":
        check_output(args.json, [args.table], force=args.force)


def write_json(path: Path | None, data: dict) -> None:
    if path is None:
        return
    text = json.dumps(data, indent=2)
    if str(path) == "-":
        print(text)
    else:
        with atomic_write(path) as f:
            f.write(text + "\n")


def print_notes(survey) -> None:
    for n in survey.notes:
        print(f"note: {n}", file=sys.stderr)


def positive(name: str, value: float) -> float:
    """``value`` if it is a finite number above 0, else a one-line CliError naming ``name``."""
    if not math.isfinite(value) or value <= 0:
        raise CliError(f"{name} must be a number above 0, not {value:g}")
    return value


def add_sample_rate(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--sample-rate",
        type=float,
        default=None,
        metavar="HZ",
        help="samples per second in the table (default: one per reading of the fastest measurement "
        "source; with a bridge, one per bridge SAMPLE)",
    )


def sample_rate(args: argparse.Namespace) -> float | None:
    """The checked ``--sample-rate``, or None for the default pacing."""
    rate = args.sample_rate
    return None if rate is None else positive("--sample-rate", rate)
