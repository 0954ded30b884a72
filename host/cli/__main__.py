"""``python -m forcemap.host.cli``: the same as the ``forcemap`` command."""

import sys

from forcemap.host.cli import main

if __name__ == "__main__":  # not when the live map process (spawned) imports this module again
    sys.exit(main())
