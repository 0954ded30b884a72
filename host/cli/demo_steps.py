"""`forcemap demo`'s steps after the survey: each a `forcemap` command in a child forked from the demo,
which has loaded the workbench once, several at a time where one does not need another's output.

A new interpreter per step spent about a second of CPU importing numpy, scipy, matplotlib, pyarrow and
the workbench (six steps); a child forked after `warm_up` starts with them loaded. On a busy machine the
demo waits for a CPU far more than it computes (issue 58: a third of a core beside two busy loops), so
the steps that do not need each other's files run side by side (`log info` beside `export`, the baseline
`fit` beside `diagnose`, which starts from the same baseline terms), each with its own share. Their output
is held in files and shown in the order the demo prints its steps, the one shown streaming live, so the
transcript is the one the commands give run one after another.
"""

from __future__ import annotations

import importlib
import os
import sys
import tempfile
import time
import traceback

# what the steps import (each command imports its work lazily): loaded once, before the first fork
WARM = (
    "numpy",
    "scipy.linalg",
    "scipy.optimize",
    "scipy.stats",
    "matplotlib.pyplot",
    "pyarrow",
    "forcemap.host.api",
    "forcemap.host.convert.export",
    "forcemap.host.convert.nav_findings",
    "forcemap.host.qa.report",
    "forcemap.host.workbench.fits.fit",
    "forcemap.host.workbench.diagnose.rounds",
    "forcemap.host.report.build",
)
POLL_S = 0.05  # how often a shown step's held output is copied out while it runs


def warm_up() -> None:
    """Import what the steps need, so each forked child starts with it (a missing one is the step's
    to report)."""
    for name in WARM:
        try:
            importlib.import_module(name)
        except Exception:
            pass


def _child(argv: list[str], out: int, err: int) -> None:
    """In the forked child: run `forcemap ARGV` with its output in the step's files; never returns."""
    code = 1
    try:
        os.dup2(out, 1)
        os.dup2(err, 2)
        # new stream objects: a lock the parent's streams held at the fork would stay held here
        sys.stdout = open(1, "w", buffering=1, closefd=False)  # noqa: SIM115
        sys.stderr = open(2, "w", buffering=1, closefd=False)  # noqa: SIM115
        from forcemap.host.cli import main

        code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    except BaseException:
        traceback.print_exc()
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


class Step:
    """One `forcemap ARGV`, started at once in a forked child; `show` prints the command and its output
    (held until then, live from then on) and waits for it."""

    def __init__(self, argv: list[str]):
        self.argv = argv
        self.files = [tempfile.TemporaryFile() for _ in range(2)]  # its stdout, its stderr
        self.shown = [0, 0]
        sys.stdout.flush()
        sys.stderr.flush()
        self.pid = os.fork()
        if self.pid == 0:
            _child(argv, self.files[0].fileno(), self.files[1].fileno())
        self.code: int | None = None

    def _copy(self) -> None:
        for i, stream in enumerate((sys.stdout, sys.stderr)):
            data = os.pread(self.files[i].fileno(), 1 << 20, self.shown[i])
            while data:
                self.shown[i] += len(data)
                stream.buffer.write(data)
                stream.flush()
                data = os.pread(self.files[i].fileno(), 1 << 20, self.shown[i])

    def wait(self) -> int:
        """Its exit code, once it has ended (its output still held)."""
        if self.code is None:
            _, status = os.waitpid(self.pid, 0)
            self.code = os.waitstatus_to_exitcode(status)
        return self.code

    def _ended(self) -> bool:
        if self.code is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid == 0:
                return False
            self.code = os.waitstatus_to_exitcode(status)
        return True

    def show(self) -> None:
        """Print the command and its output until it ends; a failed step stops the demo."""
        print("$ forcemap " + " ".join(self.argv), flush=True)
        while not self._ended():
            self._copy()
            time.sleep(POLL_S)
        self._copy()
        for f in self.files:
            f.close()
        if self.code != 0:
            raise SystemExit(
                f"demo: step failed (exit {self.code}): forcemap {' '.join(self.argv)}"
            )

    def stop(self) -> None:
        """End it if it still runs (the demo stopped early)."""
        if self.code is None:
            try:
                os.kill(self.pid, 15)
            except ProcessLookupError:
                pass
            self.wait()
