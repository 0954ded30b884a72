"""`forcemap run`: start the acquisition daemon from the command line (or systemd)."""

from __future__ import annotations

import argparse
import os
import platform
import signal
import sys
import textwrap
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from forcemap.host.acquire.arrival_clock import Clock, SimClock, parse_clock
from forcemap.host.acquire.daemon import Daemon
from forcemap.host.acquire.sources import (
    Transport,
    mavlink_opener,
    nmea_opener,
    port_opener,
    split_baud,
)
from forcemap.host.acquire.status import Reporter
from forcemap.host.cli.common import (
    add_boat,
    add_deprecated,
    add_duration,
    add_output,
    add_quiet,
    format_duration,
    positive,
)
from forcemap.host.cli.live_options import add_live_arguments, start_live
from forcemap.host.cli.pipeline_options import add_pipeline_options, sample_rate
from forcemap.host.cli.replan_options import SampleTee, add_replan_arguments, replan_service
from forcemap.host.errors import CliError
from forcemap.host.log.mcap import McapLog

BRIDGE_BAUD = 115200
NMEA_BAUD = 4800
# how long `--clock sim:PATH` waits for the simulator to write its clock file (it takes about 2 s
# to start on a busy Pi; the daemon is usually started first)
CLOCK_WAIT_S = 10.0
ROTATE_S = 3600.0

EPILOG = """\
examples:
  forcemap run --bridge /dev/ttyACM0 --nmea /dev/ttyUSB0 --mavlink /dev/ttyAMA0,57600
  forcemap run --nmea /dev/ttyUSB0,4800 --nmea /dev/ttyUSB1,38400   # NMEA only: GPS, wind
  forcemap run --nmea udp:10110                  # a WiFi multiplexer's UDP broadcast
  forcemap run --nmea socket://192.168.4.1:10110 # a multiplexer's TCP server
  forcemap run --mavlink udp:0.0.0.0:14550       # an autopilot (with an echo sounder) only
  forcemap run --bridge /tmp/ports/bridge --clock sim:/tmp/ports/clock   # with `forcemap sim`
  forcemap run --nmea /dev/ttyUSB0 --boat boat.toml -o /data/logs --rotate-every 30m --quiet

Every source is optional, but at least one is needed. See docs/DAEMON.md.

live view (docs/LIVE.md): --live serves every logged topic, /health, /alerts and the growing maps
(/map/current, /map/wind, /map/depth, GeoJSON layers under /map/layers/) to Foxglove over WebSocket
on 127.0.0.1:8765, this machine only; reach it from ashore through an SSH tunnel
(ssh -L 8765:127.0.0.1:8765 pi@boat). --live 0.0.0.0:8765 serves the boat's whole network,
unencrypted and without a password, and the daemon warns so. The MCAP is the same with or without it.
  forcemap run --nmea /dev/ttyUSB0 --mavlink /dev/ttyAMA0,57600 --live
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = textwrap.fill(
        "Read the bridge, NMEA 0183 instruments and the autopilot, align and compensate, and log "
        "to MCAP. Any source may be left out. Ports that are missing or unplugged are retried "
        "until they come back. SIGTERM or Ctrl-C closes the log cleanly.",
        88,
    )
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument(
        "--bridge",
        metavar="PORT",
        help="the MicroPython bridge: a device path or a pyserial URL (socket://, loop://); "
        f"PATH,BAUD sets the baud rate (default {BRIDGE_BAUD})",
    )
    parser.add_argument(
        "--nmea",
        metavar="PORT",
        action="append",
        default=[],
        help="an NMEA 0183 instrument (give it once per instrument): a device path (PATH,BAUD; "
        f"default {NMEA_BAUD} baud), a pyserial URL (socket://HOST:PORT), udp:[HOST:]PORT (a UDP "
        "broadcast, usually udp:10110) or tcp:HOST:PORT; the sources are named nmea, nmea2, ... "
        "in the order given",
    )
    parser.add_argument(
        "--depth", metavar="PORT", help="one more NMEA instrument, named depth (as in older logs)"
    )
    parser.add_argument(
        "--mavlink",
        metavar="CONN",
        help="the autopilot, pymavlink-style: /dev/ttyACM0,57600, udp:HOST:PORT, udpin:HOST:PORT, "
        "tcp:HOST:PORT",
    )
    add_boat(
        parser,
        "calibration and config (default: built-in defaults; see host/data/boat.example.toml)",
    )
    add_output(
        parser, "folder for the MCAP files (default logs; created if missing)", force=False,
        default="logs", metavar="DIR",
    )  # fmt: skip
    add_deprecated(parser, "--out", "-o/--output DIR", "output")
    parser.add_argument(
        "--clock",
        default="system",
        metavar="system|sim:PATH",
        help="time source for arrival stamps: the host's clocks, or the simulator's clock file",
    )
    add_duration(
        parser, "--clock-wait", CLOCK_WAIT_S,
        f"how long to wait for the simulator's clock file (default {format_duration(CLOCK_WAIT_S)})",
    )  # fmt: skip
    add_quiet(
        parser,
        "no progress (the live view); only the events, one JSON line each on stderr "
        "(for systemd/journald)",
    )
    parser.add_argument(
        "--rotate-mb", type=float, default=256.0, metavar="N", help="start a new file after N MiB"
    )
    add_duration(
        parser, "--rotate-every", ROTATE_S,
        f"start a new file after this long, host time (default {format_duration(ROTATE_S)})",
        dest="rotate_s",
    )  # fmt: skip
    add_deprecated(
        parser, "--rotate-min", "--rotate-every DURATION (e.g. 60m)", "rotate_s",
        convert=lambda n: float(n) * 60.0,
    )  # fmt: skip
    add_pipeline_options(parser)
    parser.add_argument("--prefix", default="run", help="file name prefix (default: run)")
    add_replan_arguments(parser)
    parser.add_argument(
        "--raw",
        action="store_true",
        help="also log every chunk of bytes as read (/raw/<source>, base64), for replaying later",
    )
    add_live_arguments(parser)


def nmea_sources(nmea: list[str], depth: str | None = None) -> dict[str, str]:
    """Source name -> port: ``--depth PORT`` is ``depth``, each ``--nmea PORT`` ``nmea``, ``nmea2``, ..."""
    out = {"depth": depth} if depth else {}
    for n, port in enumerate(nmea, 1):
        out["nmea" if n == 1 else f"nmea{n}"] = port
    return out


def _openers(args: argparse.Namespace) -> tuple[dict[str, Callable[[], Transport]], list[str]]:
    """An opener for every source given; the NMEA sources' names."""
    openers: dict[str, Callable[[], Transport]] = {}
    try:
        if args.bridge:
            openers["bridge"] = port_opener(*split_baud(args.bridge, BRIDGE_BAUD))
        nmea = nmea_sources(args.nmea, args.depth)
        for name, port in nmea.items():
            openers[name] = nmea_opener(port, NMEA_BAUD)
        if args.mavlink:
            openers["mavlink"] = mavlink_opener(args.mavlink)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    if not openers:
        raise CliError("give at least one of --bridge, --nmea (or --depth), --mavlink")
    return openers, list(nmea)


def start_clock(spec: str, wait_s: float) -> Clock:
    """The arrival clock; a simulator's clock file that does not appear within ``wait_s`` is an error."""
    try:
        clock = parse_clock(spec)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    if isinstance(clock, SimClock):
        deadline = time.monotonic() + wait_s
        while not os.path.exists(clock.path):
            if time.monotonic() > deadline:
                raise CliError(
                    f"the simulator's clock file {clock.path} did not appear within {wait_s:g} s; "
                    "start `forcemap sim --ports DIR` (it writes DIR/clock), or use --clock system"
                )
            time.sleep(0.05)
        try:
            clock.wall_ns()  # reads the anchor now, so a broken file is reported before the run
        except FileNotFoundError as exc:
            raise CliError(str(exc)) from None
    return clock


SOURCES_PERIOD_S = 600.0  # the sources' comparison and latency, into the log's metadata


def _pipeline_factory(
    cal: Any,
    sync: str,
    speed: float,
    sample_rate_hz: float | None = None,
    on_sample: Callable[[dict], object] | None = None,
    nmea_checksum: str = "strict",
) -> Callable[[Any], Any]:
    """Imports the pipeline when called, so the daemon can fall back to raw logging if it fails."""

    def make(sink: Any) -> Any:
        from forcemap.host.fuse import pipeline

        if on_sample is not None:
            sink = SampleTee(sink, on_sample)

        # how long a sample waits for the autopilot is host time: a busy machine's stall is
        # `speed` times longer on an accelerated simulator's clock
        hold_s = pipeline.HOLD_S * max(1.0, speed)
        return pipeline.Pipeline(
            cal,
            sink,
            sync=sync,
            hold_s=hold_s,
            sample_rate_hz=sample_rate_hz,
            sources_period_s=SOURCES_PERIOD_S,
            nmea_checksum=nmea_checksum,
            live_filter=True,  # the rows from every source, causally ([sync] live_lag_s)
        )

    return make


def _record_setup(log: McapLog, args: argparse.Namespace, nmea: list[str], sync: str) -> None:
    """The command line and the boat file as written, in the log's metadata."""
    log.metadata(
        "forcemap",
        {
            "argv": " ".join(sys.argv),
            "bridge": args.bridge or "",
            "depth": args.depth or "",
            "nmea": " ".join(args.nmea),
            "nmea_sources": " ".join(nmea),
            "mavlink": args.mavlink or "",
            "clock": args.clock,
            "sync": sync,
            "host": platform.node(),
            "pid": str(os.getpid()),
        },
    )
    # the pipeline records "calibration" and "config" (as parsed); this is the file as written
    config_text = Path(args.boat).read_text(encoding="utf-8") if args.boat else ""
    log.metadata("boat_toml", {"path": args.boat or "", "text": config_text})


def _stop_on_signals(daemon: Daemon) -> None:
    def stop(signum: int, _frame: Any) -> None:
        # no I/O here: a handler that writes could re-enter a stream the main loop is writing
        daemon.stop_signal = signal.Signals(signum).name
        daemon.request_stop()
        if signum == signal.SIGINT:  # a second Ctrl-C interrupts even a stuck shutdown
            signal.signal(signal.SIGINT, signal.default_int_handler)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)


def run(args: argparse.Namespace) -> int:
    from forcemap.host.fuse import calibration

    rotate_bytes = int(positive("--rotate-mb", args.rotate_mb) * 1024 * 1024)
    rotate_seconds = positive("--rotate-every", args.rotate_s)
    positive("--clock-wait", args.clock_wait)
    openers, nmea = _openers(args)
    svc = replan_service(args)
    try:
        cal = calibration.load(args.boat)
    except (ValueError, FileNotFoundError) as exc:  # calibration.ConfigError is a ValueError
        raise CliError(str(exc)) from None
    # the live view first: a viewer can connect while the daemon waits for its clock and ports
    reporter = Reporter(sys.stderr, live=False if args.quiet else None)
    live = start_live(args, args.output, reporter.event)
    try:
        return _run_daemon(
            args, cal, openers, nmea, rotate_bytes, rotate_seconds, reporter, live, svc
        )
    finally:
        if live is not None:
            live.close()


def _run_daemon(
    args: argparse.Namespace,
    cal: Any,
    openers: dict[str, Callable[[], Transport]],
    nmea: list[str],
    rotate_bytes: int,
    rotate_seconds: float,
    reporter: Reporter,
    live: Any,
    svc: Any = None,
) -> int:
    clock = start_clock(args.clock, args.clock_wait)
    sync = args.sync or getattr(cal, "sync", "interpolate")
    absent = [s for s in ("bridge", "mavlink") if s not in openers] + ([] if nmea else ["nmea"])
    try:
        log = McapLog(args.output, rotate_bytes=rotate_bytes, rotate_seconds=rotate_seconds,
                      prefix=args.prefix)  # fmt: skip
    except OSError as exc:
        raise CliError(f"cannot write the log in {args.output}: {exc.strerror or exc}") from None
    try:
        _record_setup(log, args, nmea, sync)
        daemon = Daemon(
            openers,
            _pipeline_factory(
                cal,
                sync,
                clock.speed,
                sample_rate(args),
                svc.sample if svc else None,
                nmea_checksum=args.nmea_checksum,
            ),
            log,
            clock=clock,
            reporter=reporter,
            absent=absent,
            record_raw=args.raw,
            taps={"mavlink": svc.feed} if svc else None,
        )
    except ValueError as exc:  # the pipeline rejects the calibration (e.g. degenerate wheels)
        log.close()
        raise CliError(str(exc)) from None
    except BaseException:
        log.close()
        raise
    if live is not None:
        live.attach(log)
    _stop_on_signals(daemon)
    if svc is not None:
        if live is not None and not getattr(args, "no_maps", False):
            svc.board = live.board  # the live map process's grids, rather than refits of our own
        if live is not None:
            svc.on_plan = live.mission.set_plan  # /map/mission on the live Map panel
        svc.box["daemon"] = daemon
        svc.stop_event = daemon.stop_event
        svc.start()
    return daemon.run()
