"""`forcemap import`: an NMEA 0183 capture or a MAVLink tlog into an MCAP log with the daemon's topics."""

from __future__ import annotations

import argparse
import os
import tempfile
import textwrap
from pathlib import Path
from typing import Any

from forcemap.host.cli.export import add_output_options, output_for
from forcemap.host.errors import CliError
from forcemap.host.outputs import atomic_path, check_output

EPILOG = """\
examples:
  forcemap import capture.nmea                 # -> capture.mcap beside it
  forcemap import flight.tlog -o logs/         # -> logs/flight.mcap
  forcemap import capture.txt --format nmea -o survey.mcap
  forcemap export survey.mcap -o survey.csv    # then the samples table, as for `forcemap run`

An existing output is replaced only with --force; a file that cannot be imported leaves nothing
behind. `forcemap export` takes the same -o and --force.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = textwrap.fill(
        "Run an existing NMEA 0183 capture or MAVLink telemetry log (.tlog) through the daemon's "
        "pipeline into an MCAP log.",
        88,
    )
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument(
        "file", metavar="FILE", help="NMEA 0183 capture (text) or MAVLink telemetry log (.tlog)"
    )
    add_output_options(parser, ".mcap")
    parser.add_argument(
        "--out", metavar="DIR", dest="out_dir", help="the older form of -o DIR (created if missing)"
    )
    parser.add_argument(
        "--format",
        choices=("nmea", "tlog"),
        default=None,
        help="input format (default: from the name and the first bytes)",
    )
    parser.add_argument(
        "--config", default=None, metavar="BOAT_TOML", help="calibration (default: built-in)"
    )
    parser.add_argument(
        "--sync",
        choices=("interpolate", "approximate"),
        default=None,
        help="boat-state matching (default: the config's sync.mode)",
    )


def _open_log(out: Path, stem: str) -> Any:
    from forcemap.host.mcap_log import McapLog

    return McapLog(out, prefix=stem, rotate_bytes=1 << 62, rotate_seconds=float("inf"))


def summary(res: Any) -> list[str]:
    """Human-readable lines about an ImportResult."""
    c = res.counters
    out = [
        f"{res.path}: {res.records} {'lines' if res.format == 'nmea' else 'packets'} ({res.format})"
    ]
    if res.format == "nmea":
        n = c["depth"]
        out.append(
            f"  NMEA: {n['accepted']} accepted {dict(sorted(n['accepted_by_type'].items()))}"
        )
        out.append(
            f"        {n['rejected']} rejected {dict(sorted(n['rejected_by_reason'].items()))}"
        )
    else:
        m = c["mavlink"]
        out.append(
            f"  MAVLink: {m['messages']} messages, {m['bad_crc']} bad CRC, {m['junk_bytes']} junk bytes"
        )
        for key, n in sorted(m["bad_crc_by_sender_msgid"].items(), key=lambda kv: -kv[1])[:5]:
            out.append(f"           bad CRC from sysid/compid/msgid {key}: {n}")
    if c.get("last_fix"):
        f = c["last_fix"]
        out.append(f"  last fix: {f['lat']:.6f}, {f['lon']:.6f}")
    out.extend("  " + note for note in res.notes)
    return out


def check_found(res: Any) -> None:
    """Refuse an import that found nothing it could read (random bytes, the wrong --format)."""
    c = res.counters
    name = Path(res.path).name
    if res.format == "nmea" and not c.get("depth", {}).get("accepted", 1):
        raise CliError(f"{name}: no valid NMEA 0183 sentence in its {res.records} lines")
    if res.format == "tlog" and not c.get("mavlink", {}).get("messages", 1):
        raise CliError(f"{name}: no MAVLink packet with a valid checksum in it")


def _output(args: argparse.Namespace, path: Path) -> Path:
    if args.out_dir is not None and args.output is not None:
        raise CliError("give -o/--output or the older --out DIR, not both")
    if args.out_dir is not None:
        try:
            Path(args.out_dir).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise CliError(f"cannot create the folder {args.out_dir} ({exc.strerror})") from None
        return Path(args.out_dir) / f"{path.stem}.mcap"
    if args.output == "-":
        raise CliError("an MCAP log needs an output file (-o FILE.mcap) or folder")
    return Path(output_for(args.output, str(path), ".mcap"))


def run(args: argparse.Namespace) -> int:
    from forcemap.host.calibration import ConfigError, load
    from forcemap.host.importers import ImportFailed, check_importable, import_file

    path = Path(args.file)
    try:
        cal = load(args.config)
        if not path.is_file():
            raise ImportFailed(f"{path}: no such file")
        fmt = check_importable(path, args.format)
    except (ConfigError, ImportFailed) as e:
        raise CliError(str(e)) from None
    out = check_output(_output(args, path), [path], args.force)
    # the log is written in a temporary folder beside the output and renamed into place whole
    with (
        atomic_path(out) as tmp,
        tempfile.TemporaryDirectory(dir=tmp.parent, prefix=".forcemap-import-") as work,
    ):
        log = _open_log(Path(work), path.stem)
        try:
            res = import_file(path, log, fmt, cal, args.sync)
        except ImportFailed as e:
            raise CliError(str(e)) from None
        finally:
            log.close()
        check_found(res)
        os.replace(log.path, tmp)
    for line in summary(res):
        print(line)
    print(f"  -> {out}")
    return 0
