"""BLAS threads wherever forcemap runs (host/workbench/engine/threads.py, issue 58): the `forcemap` command
starts numpy's BLAS on one thread unless the user's environment says otherwise, and the small
factorizations run on one whatever it says."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from forcemap.host.workbench.engine.threads import THREAD_VARS

# the command's entry point as the `forcemap` script calls it, then what numpy's BLAS libraries run on
PROBE = """
import json, sys
from forcemap.host.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
import numpy, scipy.linalg, threadpoolctl
from forcemap.host.workbench.engine.threads import small_blas
blas = lambda: sorted({d["num_threads"] for d in threadpoolctl.threadpool_info() if d["user_api"] == "blas"})
default = blas()
with small_blas():
    print(json.dumps({"default": default, "small": blas()}))
"""


def probe(*argv: str, **env: str) -> dict:
    clean = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}  # conftest sets them
    res = subprocess.run(
        [sys.executable, "-c", PROBE, *argv],
        env={**clean, **env},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    return json.loads(res.stdout.splitlines()[-1])


def test_importing_the_command_loads_no_numpy():
    """The thread count is read when numpy loads: the entry point's imports must not load it."""
    code = "import sys; import forcemap, forcemap.host.cli; print('numpy' in sys.modules)"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.stdout.strip() == "False", res.stderr


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="BLAS's own default is one thread here")
@pytest.mark.parametrize("argv", [(), ("fit", "--help")])
def test_the_command_runs_blas_on_one_thread(argv):
    seen = probe(*argv)
    assert seen == {"default": [1], "small": [1]}


def test_the_users_setting_wins_and_small_factorizations_still_take_one():
    seen = probe("fit", "--help", OPENBLAS_NUM_THREADS="2")
    assert seen == {"default": [2], "small": [1]}
