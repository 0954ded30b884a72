"""Shared CLI plumbing: table loading, error handling (one line, exit 2), JSON output."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path

from forcemap.host.errors import CliError
from forcemap.host.workbench.errors import WorkbenchError


def add_table(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "table",
        type=Path,
        help="samples table: .csv, .parquet, or an .mcap log from `forcemap run`",
    )


def teach(parser: argparse.ArgumentParser, epilog: str) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = epilog


def guarded(name: str, body: Callable[[], int]) -> int:
    """Run a command body; bad input becomes one line on stderr and exit status 2, never a traceback."""
    try:
        return body()
    except WorkbenchError as exc:
        print(f"forcemap {name}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `forcemap ... | head`: the reader left, which is fine
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


def write_json(path: Path | None, data: dict) -> None:
    if path is None:
        return
    text = json.dumps(data, indent=2)
    if str(path) == "-":
        print(text)
    else:
        Path(path).write_text(text + "\n")


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
