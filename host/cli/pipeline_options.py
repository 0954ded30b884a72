"""The options of the pipeline that reads a boat's sources, which `run`, `import` and `check` share:
how a sample meets the boat's state (--sync), how many samples a second (--sample-rate), which NMEA
checksums count (--nmea-checksum), and the day of an NMEA log without one (--date)."""

from __future__ import annotations

import argparse
import datetime

from forcemap.host.cli.common import positive


def add_sync(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--sync",
        choices=("interpolate", "approximate"),
        default=None,
        help="boat-state matching: interpolate at each sample's time (default), or the paper's "
        "nearest-neighbour ApproximateTime scheme; overrides the sync.mode of --boat",
    )


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


def add_pipeline_options(parser: argparse.ArgumentParser) -> None:
    """What `run` and `import` share of the pipeline's options: --sync, --sample-rate, --nmea-checksum."""
    add_sync(parser)
    add_sample_rate(parser)
    add_nmea_checksum(parser)


def add_log_date(parser: argparse.ArgumentParser) -> None:
    """--date: the UTC day an NMEA log without a date (GGA or GLL, no RMC or ZDA) starts on."""
    parser.add_argument(
        "--date",
        type=log_day,
        metavar="YYYY-MM-DD",
        help="the UTC day an NMEA log starts on, for a log whose sentences carry no date (GGA or "
        "GLL without RMC or ZDA, or whose only dates come without a fix): the magnetic "
        "declination, tides and --at need it; a log's own date (its valid fixes') is used "
        "before it",
    )


def log_day(text: str) -> float:
    """``YYYY-MM-DD`` to the UNIX time of that day's UTC midnight (argparse: one line, exit 2)."""
    try:
        day = datetime.date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a day (YYYY-MM-DD)") from None
    return datetime.datetime(day.year, day.month, day.day, tzinfo=datetime.UTC).timestamp()


def add_nmea_checksum(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--nmea-checksum",
        choices=("strict", "lenient"),
        default="strict",
        help="strict (default): an NMEA sentence whose checksum fails is rejected; lenient: one "
        "whose checksum was computed by a known variant (over the address only, without the last "
        "field, with the $) is accepted and counted (docs/DAEMON.md)",
    )
