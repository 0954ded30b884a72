"""`forcemap replay LOG.mcap --live`: stream a finished log to Foxglove as if live, maps recomputed as they grew."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from forcemap.host.cli.common import add_quiet
from forcemap.host.cli.live_options import add_live_arguments, start_live
from forcemap.host.errors import CliError

EPILOG = """\
examples:
  forcemap replay logs/run-20261124T101500Z.mcap --live              # at the pace it was logged
  forcemap replay logs/run-*.mcap --live --speed 10                  # ten times faster
  forcemap replay run.mcap --live 0.0.0.0:8765 --speed 5 --map-every 30s

Every message goes out on its topic with its schema from the log; /health, /alerts and the growing
maps (/map/<target>, /map/layers/...) are computed again as if live, from the log's own clock, so a
replay at any speed shows the maps the boat would have shown. Connect Foxglove to ws://HOST:PORT
(docs/LIVE.md). Ctrl-C stops.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument(
        "logs", nargs="+", type=Path, metavar="LOG.mcap", help="MCAP log(s), in order"
    )
    add_live_arguments(parser)
    parser.add_argument(
        "--speed", type=float, default=1.0, metavar="X", help="times real time (default 1)"
    )
    add_quiet(parser)


def _messages(paths: list[Path]):
    """(topic, log_time_ns, data, (schema name, schema)) in file order, the bytes as logged."""
    from forcemap.host.log.mcap import FileScan, iter_records
    from mcap.records import Message

    for path in paths:
        scan = FileScan(path)
        for rec in iter_records(path, scan):
            if not isinstance(rec, Message):
                continue
            ch = scan.channels.get(rec.channel_id)
            if ch is None:
                continue
            schema = scan.schemas.get(ch.schema_id)
            try:
                parsed = (schema.name, json.loads(schema.data)) if schema is not None else None
            except ValueError:
                parsed = None
            yield ch.topic, rec.log_time, bytes(rec.data), parsed


def run(args: argparse.Namespace) -> int:
    if args.live is None:
        raise CliError("replay streams to Foxglove: add --live [HOST:PORT] (docs/LIVE.md)")
    if not math.isfinite(args.speed) or args.speed <= 0:
        raise CliError(f"--speed must be a number above 0, not {args.speed:g}")
    for p in args.logs:
        if not p.is_file():
            raise CliError(f"{p}: no such file")

    def event(name: str, **fields) -> None:
        if not args.quiet or name == "warning":
            print(f"{name}: " + " ".join(f"{k}={v}" for k, v in fields.items()), file=sys.stderr)

    live = start_live(args, None, event)
    n = 0
    try:
        n = _stream(live, args.logs, args.speed)
    except KeyboardInterrupt:
        print("replay: interrupted", file=sys.stderr)
    finally:
        live.close(final_maps_s=300.0)
    print(
        f"replayed {n} messages from {len(args.logs)} file(s); maps updated {live.board.updates} times"
    )
    return 0


def _stream(live, paths: list[Path], speed: float) -> int:
    """Offer every message at its time / speed; waits (never drops) when the publisher is behind."""
    start_wall = time.monotonic()
    first = None
    n = 0
    for topic, t_ns, data, schema in _messages(paths):
        if schema is not None and topic not in live.server.channels:
            live.server.schemas[topic] = schema
        first = t_ns if first is None else first
        wait = (t_ns - first) / 1e9 / speed - (time.monotonic() - start_wall)
        if wait > 0:
            time.sleep(wait)
        while len(live.tee) > live.tee.maxlen // 2:
            time.sleep(0.01)
        live.tee.offer(topic, t_ns, data, None)
        n += 1
    return n
