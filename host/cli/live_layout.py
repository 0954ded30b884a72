"""`forcemap live-layout -o forcemap.json`: the Foxglove layout for the live view (import it in Foxglove)."""

from __future__ import annotations

import argparse

from forcemap.host.cli.common import add_output

EPILOG = """\
examples:
  forcemap live-layout -o forcemap.json

In Foxglove: Layouts > Import from file. The layout has a Map panel (the track /fix and the live map
layers), plots of current, wind and depth against time, the /health table and the /alerts log.
See docs/LIVE.md.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    add_output(parser, "the layout file to write (JSON)", required=True)


def run(args: argparse.Namespace) -> int:
    from forcemap.host.live.layout import layout_json
    from forcemap.host.outputs import atomic_write, check_output

    out = check_output(args.output, force=args.force)
    with atomic_write(out) as f:
        f.write(layout_json())
    print(f"wrote {out}")
    return 0
