"""`forcemap demo`, the README's main command, runs every step on a short survey."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from forcemap.host.log.mcap import has_footer


@pytest.mark.slow
def test_demo_runs_the_whole_story(tmp_path):
    out = tmp_path / "demo"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "forcemap.host.cli",
            "demo",
            "-o",
            str(out),
            "--duration",
            "6m",
            "--speed",
            "80",
        ],
        capture_output=True,
        text=True,
        # generous: in lockstep a busy machine makes the survey slower, never different
        timeout=1800,
    )
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    mcaps = sorted((out / "logs").glob("*.mcap"))
    assert mcaps and all(has_footer(p) for p in mcaps)
    assert (out / "survey.csv").stat().st_size > 10_000
    baseline = json.loads((out / "fit-baseline.json").read_text())
    assert baseline["target"] == "current_speed" and baseline["cv_rmse"] > 0
    diag = json.loads((out / "diagnosis.json").read_text())
    assert diag["baseline"]["cv_rmse"] == pytest.approx(baseline["cv_rmse"], rel=0.2)
    html = (out / "report.html").read_text()
    assert "<img" in html and "data:image/png;base64," in html
    assert "blocked-CV RMSE" in res.stdout and str(out / "report.html") in res.stdout
    # the simulator's clock drove the daemon: every chunk waited for, none given up on
    assert "lockstep with the daemon:" in res.stdout and " 0 timeouts" in res.stdout
