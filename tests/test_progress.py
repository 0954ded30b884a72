"""Progress on stderr: rewritten in place on a terminal, one line per step in a log file (issue 33)."""

from __future__ import annotations

import subprocess
import sys

from forcemap.host.progress import Progress

from tests.test_daemon_support import ROOT


def test_a_log_file_gets_one_line_per_step(tmp_path):
    # stderr redirected to a file, as under nohup, cron or systemd
    code = (
        "from forcemap.host.progress import Progress\n"
        "p = Progress('evaluating', 3)\n"
        "for w in ('depth', 't', 'heading'): p.step(w)\n"
        "p.close()\n"
    )
    log = tmp_path / "stderr.log"
    with log.open("w") as err:
        subprocess.run([sys.executable, "-c", code], cwd=ROOT, stderr=err, check=True, timeout=60)
    text = log.read_text()
    assert "\r" not in text
    lines = text.splitlines()
    assert [ln.split(" (")[0] for ln in lines] == [
        "evaluating: 1/3 depth",
        "evaluating: 2/3 t",
        "evaluating: 3/3 heading",
    ]


def test_a_terminal_gets_one_line_rewritten(capsys):
    p = Progress("evaluating", 2, terminal=True)
    p.step("depth")
    p.step("t")
    p.close()
    err = capsys.readouterr().err
    assert err.count("\r") == 2 and err.count("\n") == 1 and err.endswith("\n")


def test_disabled_is_silent(capsys):
    p = Progress("evaluating", 2, enabled=False, terminal=False)
    p.step("depth")
    p.close()
    assert capsys.readouterr().err == ""
