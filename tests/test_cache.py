"""tests/cache.py: two xdist workers asking at once get one build; a failed build leaves nothing."""

from __future__ import annotations

import multiprocessing as mp
import os
import time
from pathlib import Path

import pytest

from tests.cache import run_dir, shared_dir, shared_value


class _Worker:
    """A worker's tmp_path_factory, as xdist lays it out: <run's basetemp>/popen-gwN."""

    def __init__(self, base: Path):
        self.base = base

    def getbasetemp(self) -> Path:
        self.base.mkdir(parents=True, exist_ok=True)
        return self.base


def _build_slowly(folder: Path, ledger: Path) -> None:
    with open(ledger, "a") as f:
        f.write(f"{os.getpid()}\n")
    time.sleep(0.5)  # long enough that the other worker arrives during the build
    (folder / "data.txt").write_text(f"built by {os.getpid()}")


def _worker(base: str, name: str, ledger: str, out: str, start) -> None:
    os.environ["PYTEST_XDIST_WORKER"] = name
    start.wait(60)  # both ask at the same moment
    folder = shared_dir(
        _Worker(Path(base) / f"popen-{name}"),
        "slow build",
        lambda d: _build_slowly(d, Path(ledger)),
    )
    Path(out).write_text(f"{folder}\n{(folder / 'data.txt').read_text()}")


def test_two_workers_at_once_build_once_and_see_the_same_folder(tmp_path):
    ledger = tmp_path / "builds.txt"
    ctx = mp.get_context("spawn")
    start = ctx.Barrier(2)
    procs = [
        ctx.Process(target=_worker, args=(str(tmp_path), n, str(ledger), str(tmp_path / n), start))
        for n in ("gw0", "gw1")
    ]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
        assert p.exitcode == 0
    assert len(ledger.read_text().split()) == 1
    seen = {(tmp_path / n).read_text() for n in ("gw0", "gw1")}
    assert len(seen) == 1
    folder = Path(seen.pop().splitlines()[0])
    assert folder.parent == tmp_path / "shared" and not list(folder.parent.glob("*.building.*"))


def test_a_failed_build_leaves_nothing_and_the_next_caller_builds(tmp_path_factory):
    calls = []

    def fails(folder: Path) -> None:
        calls.append("fail")
        (folder / "half.txt").write_text("half")
        raise RuntimeError("the build broke")

    with pytest.raises(RuntimeError):
        shared_dir(tmp_path_factory, "breaks once", fails)
    root = run_dir(tmp_path_factory)
    assert not [p for p in root.iterdir() if p.name.startswith("breaks_once") and p.is_dir()]
    assert shared_value(tmp_path_factory, "breaks once", lambda: {"n": 2}) == {"n": 2}
    assert shared_value(tmp_path_factory, "breaks once", lambda: {"n": 3}) == {"n": 2}  # built
    assert calls == ["fail"]
