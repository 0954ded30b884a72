"""``python -m forcemap.host.cli``: the same as the ``forcemap`` command."""

import sys

from forcemap.host.cli import main

sys.exit(main())
