"""Build once per test run, share with every xdist worker: a folder on disk, or a value pickled in one.

Under ``pytest -n 2`` each worker is its own session, so a session-scoped fixture alone still builds
its data once per worker. ``shared_dir(factory, key, build)`` builds in a folder all workers of a run
share (the parent of each worker's basetemp; without xdist, the session's own basetemp, so nothing
outlives the run and a code change is never served stale data):

- the first caller takes an exclusive lock (``fcntl.flock`` on ``<key>.lock``: the kernel releases it
  if the worker dies), builds into a fresh temporary folder and renames it to ``<key>`` when complete;
- a caller that finds ``<key>`` uses it at once; one that arrives during the build waits on the lock;
- a build that raises leaves nothing behind, and the next caller builds again (and fails again, in its
  own test, if the failure is real).

Use it under a session-scoped fixture (one build per worker process at most, then one per run):

    @pytest.fixture(scope="session")
    def paccup_import(tmp_path_factory):
        return shared_dir(tmp_path_factory, "paccup-import", lambda d: _import(PACCUP, d))

``build_once(folder, build)`` is the same for a folder of the caller's choosing (tests/real_cases.py
keeps its cases in a folder of its own under ``run_dir``). Keys name what is built and from what (``nmea-PacCupStartNMEA.txt-import``); two builders with
different recipes must not share a key. ``shared_value`` is the same for a picklable result.
"""

from __future__ import annotations

import fcntl
import os
import pickle
import re
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import pytest

T = TypeVar("T")
_SAFE = re.compile(r"[^A-Za-z0-9._-]")


def run_dir(factory: pytest.TempPathFactory) -> Path:
    """The folder this run's workers share: the controller's basetemp under xdist, else our own."""
    base = factory.getbasetemp()
    root = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "shared"
    root.mkdir(exist_ok=True)
    return root


def build_once(folder: Path, build: Callable[[Path], Any]) -> Path:
    """``folder``, made by ``build(tmp)`` (which fills the empty folder ``tmp``, renamed to ``folder``
    when it returns) the first time any process asks; the others wait for it."""
    if folder.is_dir():
        return folder
    with open(folder.with_name(f"{folder.name}.lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, or the process ends
        if not folder.is_dir():
            work = Path(tempfile.mkdtemp(prefix=f"{folder.name}.building.", dir=folder.parent))
            try:
                build(work)
            except BaseException:
                shutil.rmtree(work, ignore_errors=True)
                raise
            os.replace(work, folder)
    return folder


def shared_dir(factory: pytest.TempPathFactory, key: str, build: Callable[[Path], Any]) -> Path:
    """The folder ``key`` of the run's shared folder, made by ``build(folder)`` (which fills the
    empty folder it is given) once per test run, whichever worker asks first."""
    return build_once(run_dir(factory) / _SAFE.sub("_", key), build)


def shared_value(factory: pytest.TempPathFactory, key: str, compute: Callable[[], T]) -> T:
    """``compute()``, computed once per test run and pickled in the shared folder ``key``."""

    def build(folder: Path) -> None:
        with open(folder / "value.pickle", "wb") as f:
            pickle.dump(compute(), f, protocol=pickle.HIGHEST_PROTOCOL)

    with open(shared_dir(factory, key, build) / "value.pickle", "rb") as f:
        return pickle.load(f)
