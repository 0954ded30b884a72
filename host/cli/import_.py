"""`forcemap import`: an NMEA 0183 capture, a MAVLink tlog, a DataFlash log or a TRDI PD0 ADCP file into an
MCAP log with the daemon's topics (the ADCP's: forcemap.host.convert.adcp_import)."""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path
from typing import Any

from forcemap.host.cli.common import add_boat, add_deprecated, add_output, output_for
from forcemap.host.cli.pipeline_options import add_log_date, add_pipeline_options, sample_rate
from forcemap.host.errors import CliError
from forcemap.host.outputs import check_output

EPILOG = """\
examples:
  forcemap import capture.nmea                 # -> capture.mcap beside it
  forcemap import race.nmea.gz -o race.mcap    # gzipped: read as the file it holds
  forcemap import flight.tlog -o logs/         # -> logs/flight.mcap
  forcemap import capture.txt --from nmea -o survey.mcap --boat boat.toml
  forcemap import transect.PD0 --reference gps # a moving-boat ADCP (the [adcp] extra)
  forcemap import sounder.nmea --date 2024-06-12 # GGA without RMC: the log's own day
  forcemap export survey.mcap -o survey.csv    # then the samples table, as for `forcemap run`

An existing output is replaced only with --force; a file that cannot be imported leaves nothing
behind. `forcemap export` takes the same -o and --force.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = textwrap.fill(
        "Run an existing NMEA 0183 capture, MAVLink telemetry log (.tlog) or ArduPilot DataFlash "
        "log (.BIN) through the daemon's pipeline into an MCAP log with the samples table; or read "
        "a TRDI PD0 ADCP transect (.PD0, .000) into one, with its profiles and QA (docs/ADCP.md).",
        88,
    )
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument(
        "file",
        metavar="FILE",
        help="NMEA 0183 capture (text), MAVLink telemetry log (.tlog), DataFlash log (.BIN) or "
        "TRDI PD0 ADCP file; a capture or tlog may be gzipped (capture.nmea.gz)",
    )
    add_output(
        parser,
        "output file, or an existing folder for one named like the input (.mcap); "
        "default: beside the input",
        metavar="OUT",
    )
    add_deprecated(parser, "--out", "-o/--output DIR (an existing folder)", "out_dir")
    parser.add_argument(
        "--from",
        dest="source_format",
        choices=("nmea", "tlog", "dataflash", "adcp"),
        default=None,
        help="the input's format (default: from the name and the first bytes)",
    )
    add_deprecated(parser, "--format", "--from nmea|tlog|dataflash|adcp", "source_format")
    parser.add_argument(
        "--reference",
        choices=("bt", "gps"),
        default="bt",
        help="ADCP only: the boat's velocity over ground from bottom track (default, as WinRiver) "
        "or GPS",
    )
    parser.add_argument(
        "--heading-offset",
        type=float,
        default=None,
        metavar="DEG",
        help="ADCP only: pin the compass correction (deg, added to the heading) instead of "
        "estimating it from bottom track against GPS",
    )
    add_boat(parser, "calibration (default: built-in; see host/data/boat.example.toml)")
    add_pipeline_options(parser)
    add_log_date(parser)


_UNITS = {"nmea": "lines", "tlog": "packets", "dataflash": "records", "adcp": "ensembles"}


def summary(res: Any) -> list[str]:
    """Human-readable lines about an ImportResult."""
    c = res.counters
    out = [f"{res.path}: {res.records} {_UNITS[res.format]} ({res.format})"]
    if res.format == "nmea":
        n = c["nmea"]
        out.append(
            f"  NMEA: {n['accepted']} accepted {dict(sorted(n['accepted_by_type'].items()))}"
        )
        out.append(
            f"        {n['rejected']} rejected {dict(sorted(n['rejected_by_reason'].items()))}"
        )
    elif res.format == "tlog":
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
    """Refuse an import that found nothing it could read (random bytes, the wrong --from)."""
    c = res.counters
    name = Path(res.path).name
    if res.format == "nmea" and not c.get("nmea", {}).get("accepted", 1):
        raise CliError(f"{name}: no valid NMEA 0183 sentence in its {res.records} lines")
    if res.format == "tlog" and not c.get("mavlink", {}).get("messages", 1):
        raise CliError(f"{name}: no MAVLink packet with a valid checksum in it")


def _output(args: argparse.Namespace, path: Path) -> Path:
    out_dir = getattr(args, "out_dir", None)  # the old --out DIR, which creates the folder
    if out_dir is not None and args.output is not None:
        raise CliError("give -o/--output or the older --out DIR, not both")
    if out_dir is not None:
        try:
            Path(out_dir).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise CliError(f"cannot create the folder {out_dir} ({exc.strerror})") from None
        return Path(out_dir) / f"{path.stem}.mcap"
    if args.output == "-":
        raise CliError("an MCAP log needs an output file (-o FILE.mcap) or folder")
    return Path(output_for(args.output, str(path), ".mcap"))


def run(args: argparse.Namespace) -> int:
    from forcemap.host.convert.importers import ImportFailed, check_importable
    from forcemap.host.convert.self_calibration import import_calibrated
    from forcemap.host.fuse.calibration import ConfigError, load
    from forcemap.host.qa.report import summary as qa_summary

    path = Path(args.file)
    try:
        cal = load(args.boat)
        if not path.is_file():
            raise ImportFailed(f"{path}: no such file")
        fmt = check_importable(path, args.source_format)
    except (ConfigError, ImportFailed) as e:
        raise CliError(str(e)) from None
    out = check_output(_output(args, path), [path], args.force)
    if fmt == "adcp":
        return _run_adcp(args, path, out)
    try:
        res, findings = import_calibrated(
            path,
            out,
            fmt,
            cal,
            args.sync,
            check=check_found,
            sample_rate_hz=sample_rate(args),
            nmea_checksum=args.nmea_checksum,
            day=args.date,
        )
    except ImportFailed as e:
        raise CliError(str(e)) from None
    for line in summary(res):
        print(line)
    for line in qa_summary(findings):  # `forcemap check` gives the whole report
        print("  " + line)
    print(f"  -> {out}")
    return 0


def _run_adcp(args: argparse.Namespace, path: Path, out: Path) -> int:
    from forcemap.host.convert.adcp_import import import_adcp_to_mcap
    from forcemap.host.convert.importers import ImportFailed

    try:
        res, _ = import_adcp_to_mcap(path, out, args.reference, args.heading_offset)
    except ImportFailed as e:
        raise CliError(str(e)) from None
    for line in summary(res):
        print(line)
    print(f"  -> {out}")
    return 0
