"""`--live [HOST:PORT]` and its options, shared by `forcemap run` and `forcemap replay`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from forcemap.host.cli.common import add_duration
from forcemap.host.extras import install_hint

LIVE_HELP = (
    "serve everything logged, /health, /alerts and the growing maps to Foxglove (WebSocket) on "
    "HOST:PORT (default 127.0.0.1:8765: this machine only). 0.0.0.0:8765 lets anyone on the boat's "
    "network watch, and says so. Needs {install}; see docs/LIVE.md"
)


def add_live_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--live", nargs="?", const="127.0.0.1:8765", default=None, metavar="HOST:PORT",
        help=LIVE_HELP.replace("{install}", install_hint("live")),
    )  # fmt: skip
    add_duration(
        parser, "--map-every", 60.0,
        "with --live: update the maps this often, in survey time (default 60s), and at the end of "
        "every line",
    )  # fmt: skip
    parser.add_argument(
        "--no-maps", action="store_true", help="with --live: no growing maps (no map process)"
    )


def start_live(args: argparse.Namespace, disk_path: str | Path | None, event: Any) -> Any:
    """The running `LiveService`, or None without ``--live``; ``event(name, **fields)`` reports."""
    if args.live is None:
        return None
    from forcemap.host.live.server import PUBLIC_WARNING, is_private, parse_address, require_sdk

    host, port = parse_address(args.live)
    require_sdk()
    from forcemap.host.live.service import LiveService

    service = LiveService(
        host, port, disk_path=disk_path, maps=not args.no_maps, every_s=args.map_every
    )
    event(
        "live", address=service.address, connect=f"ws://{connect_host(host)}:{service.server.port}"
    )
    if not is_private(host):
        warning = PUBLIC_WARNING.format(host=host, port=service.server.port)
        event("warning", reason="live_public", detail=warning)
        print(f"forcemap: warning: {warning}", file=sys.stderr, flush=True)
    return service


def connect_host(host: str) -> str:
    """What a viewer types: this machine's name stands in for "every interface"."""
    if host in ("0.0.0.0", "::", ""):
        import socket

        return socket.gethostname()
    return host
