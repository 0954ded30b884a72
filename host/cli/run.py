"""`forcemap run`: start the acquisition daemon from the command line (or systemd)."""

from __future__ import annotations

import argparse
import os
import platform
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from forcemap.host.arrival_clock import parse_clock
from forcemap.host.daemon import Daemon
from forcemap.host.mcap_log import McapLog
from forcemap.host.sources import Transport, mavlink_opener, port_opener
from forcemap.host.status import Reporter

EXIT_CONFIG = 2
DEFAULT_BAUD = {"bridge": 115200, "depth": 4800}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Read the bridge, the depth sounder and the autopilot, align and compensate, and log to MCAP. "
        "Any source may be left out. Ports that are missing or unplugged are retried until they come "
        "back. SIGTERM or Ctrl-C closes the log cleanly."
    )
    parser.add_argument(
        "--bridge",
        metavar="PORT",
        help="the MicroPython bridge: a device path or a pyserial URL (socket://, loop://); "
        "PATH,BAUD sets the baud rate (default 115200)",
    )
    parser.add_argument(
        "--depth",
        metavar="PORT",
        help="the NMEA 0183 depth sounder, as for --bridge (default 4800 baud)",
    )
    parser.add_argument(
        "--mavlink",
        metavar="CONN",
        help="the autopilot, pymavlink-style: /dev/ttyACM0,57600, udp:HOST:PORT, udpin:HOST:PORT, "
        "tcp:HOST:PORT",
    )
    parser.add_argument(
        "--config",
        metavar="BOAT_TOML",
        help="calibration and config (default: built-in defaults; see host/data/boat.example.toml)",
    )
    parser.add_argument("--out", metavar="DIR", default="logs", help="directory for MCAP files")
    parser.add_argument(
        "--clock",
        default="system",
        metavar="system|sim:PATH",
        help="time source for arrival stamps: the host's clocks, or the simulator's clock file",
    )
    parser.add_argument(
        "--quiet",
        action="store_true",
        help="no live view: one JSON line per event on stderr (for systemd/journald)",
    )
    parser.add_argument(
        "--rotate-mb", type=float, default=256.0, metavar="N", help="start a new file after N MiB"
    )
    parser.add_argument(
        "--rotate-min",
        type=float,
        default=60.0,
        metavar="N",
        help="start a new file after N minutes (host time)",
    )
    parser.add_argument(
        "--sync",
        choices=("interpolate", "approximate"),
        default=None,
        help="boat-state matching: interpolate at each sample's time (default), or the paper's "
        "nearest-neighbour ApproximateTime scheme; overrides sync.mode in the config",
    )
    parser.add_argument("--prefix", default="run", help="file name prefix (default: run)")
    parser.add_argument(
        "--raw",
        action="store_true",
        help="also log every chunk of bytes as read (/raw/<source>, base64), for replaying later",
    )


def _split_baud(port: str, default: int) -> tuple[str, int]:
    path, comma, baud = port.rpartition(",")
    if comma and baud.isdigit():
        return path, int(baud)
    return port, default


def _load_calibration(path: str | None) -> Any:
    from forcemap.host import calibration

    loader = getattr(calibration, "load_calibration", None) or calibration.load
    return loader(path)


def _pipeline_factory(cal: Any, sync: str, speed: float) -> Callable[[Any], Any]:
    """Imports the pipeline when called, so the daemon can fall back to raw logging if it fails."""

    def make(sink: Any) -> Any:
        from forcemap.host import pipeline

        # how long a sample waits for the autopilot is host time: a busy machine's stall is
        # `speed` times longer on an accelerated simulator's clock
        hold_s = pipeline.HOLD_S * max(1.0, speed)
        return pipeline.Pipeline(cal, sink, sync=sync, hold_s=hold_s)

    return make


def run(args: argparse.Namespace) -> int:
    reporter = Reporter(sys.stderr, live=False if args.quiet else None)
    try:
        cal = _load_calibration(args.config)
        clock = parse_clock(args.clock)
        clock.wall_ns()  # a simulator clock waits here for its file
    except (ValueError, FileNotFoundError) as exc:  # calibration.ConfigError is a ValueError
        print(f"forcemap run: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    sync = args.sync or getattr(cal, "sync", "interpolate")
    openers: dict[str, Callable[[], Transport]] = {}
    absent = []
    for name in ("bridge", "depth"):
        port = getattr(args, name)
        if port:
            path, baud = _split_baud(port, DEFAULT_BAUD[name])
            openers[name] = port_opener(path, baud)
        else:
            absent.append(name)
    if args.mavlink:
        try:
            openers["mavlink"] = mavlink_opener(args.mavlink)
        except ValueError as exc:
            print(f"forcemap run: {exc}", file=sys.stderr)
            return EXIT_CONFIG
    else:
        absent.append("mavlink")
    if not openers:
        print("forcemap run: give at least one of --bridge, --depth, --mavlink", file=sys.stderr)
        return EXIT_CONFIG

    try:
        log = McapLog(
            args.out,
            rotate_bytes=int(args.rotate_mb * 1024 * 1024),
            rotate_seconds=args.rotate_min * 60.0,
            prefix=args.prefix,
        )
    except OSError as exc:
        print(f"forcemap run: cannot write the log in {args.out}: {exc}", file=sys.stderr)
        return 1
    try:
        log.metadata(
            "forcemap",
            {
                "argv": " ".join(sys.argv),
                "bridge": args.bridge or "",
                "depth": args.depth or "",
                "mavlink": args.mavlink or "",
                "clock": args.clock,
                "sync": sync,
                "host": platform.node(),
                "pid": str(os.getpid()),
            },
        )
        # the pipeline records "calibration" and "config" (as parsed); this is the file as written
        config_text = Path(args.config).read_text(encoding="utf-8") if args.config else ""
        log.metadata("boat_toml", {"path": args.config or "", "text": config_text})
        daemon = Daemon(
            openers,
            _pipeline_factory(cal, sync, clock.speed),
            log,
            clock=clock,
            reporter=reporter,
            absent=absent,
            record_raw=args.raw,
        )
    except ValueError as exc:  # the pipeline rejects the calibration (e.g. degenerate wheels)
        log.close()
        print(f"forcemap run: {exc}", file=sys.stderr)
        return EXIT_CONFIG
    except BaseException:
        log.close()
        raise

    def stop(signum: int, _frame: Any) -> None:
        # no I/O here: a handler that writes could re-enter a stream the main loop is writing
        daemon.stop_signal = signal.Signals(signum).name
        daemon.request_stop()
        if signum == signal.SIGINT:  # a second Ctrl-C interrupts even a stuck shutdown
            signal.signal(signal.SIGINT, signal.default_int_handler)

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    return daemon.run()
