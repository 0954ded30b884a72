"""`--at TIME` on `fit` and `grid`: the time a prediction or a map is for (host/workbench/survey/at_time.py)."""

from __future__ import annotations

import argparse


def add_at(parser: argparse.ArgumentParser, what: str) -> None:
    """`--at TIME`: ISO 8601 with its zone, UNIX seconds, or now (host/workbench/survey/at_time.py)."""
    parser.add_argument(
        "--at",
        metavar="TIME",
        help=f"{what}: ISO 8601 with its zone (2026-06-02T14:00Z, 2026-06-02T14:00+02:00), UNIX "
        "time, or now (default: the survey's mid-time). A tide term predicts there; a GP in t "
        "reverts to its mean beyond its lengthscale from the survey, and the output says so",
    )


def at_time(args: argparse.Namespace) -> float | None:
    """`--at` as UNIX seconds (None when not given); a bad one is one line and exit 2."""
    from forcemap.host.workbench.survey.at_time import parse_at

    return None if getattr(args, "at", None) is None else parse_at(args.at)
