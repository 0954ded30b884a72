"""`forcemap live-layout -o forcemap.json`: the Foxglove layout for the live view (import it in Foxglove)."""

from __future__ import annotations

import argparse
from pathlib import Path

from forcemap.host.cli.common import add_output

EPILOG = """\
examples:
  forcemap live-layout -o forcemap.json
  forcemap live-layout -o forcemap.json --png layout.png     # and a schematic picture of it

In Foxglove: Layouts > Import from file. The layout has a Map panel (the track /fix and the live map
layers), plots of current, wind and depth against time, the /health table and the /alerts log.
See docs/LIVE.md.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    add_output(parser, "the layout file to write (JSON)", required=True)
    parser.add_argument("--png", type=Path, help="also draw a schematic of the layout (PNG)")


def run(args: argparse.Namespace) -> int:
    from forcemap.host.live.layout import layout_json, schematic_png
    from forcemap.host.outputs import atomic_path, atomic_write, check_output

    out = check_output(args.output, force=args.force)
    png = check_output(args.png, force=args.force) if args.png else None
    with atomic_write(out) as f:
        f.write(layout_json())
    print(f"wrote {out}")
    if png is not None:
        with atomic_path(png) as tmp:
            schematic_png(tmp)
        print(f"wrote {png} (a schematic, not a screenshot)")
    return 0
