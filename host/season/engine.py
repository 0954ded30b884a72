"""Where the per-log work runs: in this process, or on a Dask cluster (`--dask local[:N]` starts a
LocalCluster of N single-threaded worker processes, `--dask tcp://HOST:8786` joins a running scheduler).

Both runners give the same answers in the same order: `map_reduce` returns every log's result (in the
order of the logs) and the tree sum of their summable parts, paired level by level in the same fixed
shape, so the season's statistics are the same to the last bit whichever runs them. On Dask the pair sums
are tasks on the workers; each log's result is fetched as soon as it is done and dropped by the client, so
a worker holds one log's samples while it works on it and the m x m results until they are summed.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from typing import Any

from forcemap.host.errors import CliError
from forcemap.host.extras import install_hint

QUIET_TIMERS = {
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.scheduler.work-stealing-interval": "1s",
    "distributed.admin.tick.interval": "200ms",
    # the statistical profiler samples the task's stack every 10 ms, holding the worker's interpreter
    "distributed.worker.profile.enabled": False,
}


def summable(x: Any):
    """The part of a log's result that the tree reduction sums (None for a rejected log)."""
    return getattr(x, "stats", x) if x is not None and not hasattr(x, "reason") else None


def add_pair(a: Any, b: Any):
    a, b = summable(a), summable(b)
    if a is None:
        return b
    return a if b is None else a + b


def tree_shape(items: list, add: Callable) -> Any:
    """Pairwise sums level by level: (0+1), (2+3), ... then again, the last odd one carried up."""
    level = list(items)
    while len(level) > 1:
        nxt = [add(level[i], level[i + 1]) for i in range(0, len(level) - 1, 2)]
        if len(level) % 2:
            nxt.append(level[-1])
        level = nxt
    return level[0] if level else None


class LocalRunner:
    """Everything in this process, one log after another."""

    workers = 1
    name = "one process"

    def map(self, fn: Callable, items: list, *args, progress=None) -> list:
        out = []
        for i, item in enumerate(items):
            out.append(fn(item, *args))
            if progress:
                progress(i + 1, len(items))
        return out

    def map_reduce(self, fn: Callable, items: list, *args, progress=None):
        results = self.map(fn, items, *args, progress=progress)
        return results, summable(tree_shape(results, add_pair))

    def close(self) -> None:
        pass


class DaskRunner:
    """The same work as tasks on a Dask cluster."""

    def __init__(self, address: str) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise CliError(f"--dask needs Dask and distributed: {install_hint('dask')}") from None
        self.cluster = None
        if address == "local" or address.startswith("local:"):
            import dask

            n = _workers(address)
            # housekeeping every second, not every 0.1 s: on a machine with a core per worker, the client's
            # scheduler and nannies and the workers' own timers take their CPU from the workers' share
            with dask.config.set(QUIET_TIMERS):
                self.cluster = LocalCluster(
                    n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0"
                )
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(address, timeout=30)
            except (OSError, TimeoutError, ValueError) as e:
                raise CliError(f"cannot reach the Dask scheduler at {address}: {e}") from None
        # the workers import the per-log code now, as this process already has: not in the first tasks
        self.client.run(_warm_up)
        self.workers = len(self.client.scheduler_info(n_workers=-1)["workers"])
        self.name = f"Dask, {self.workers} worker(s) at {self.client.scheduler.address}"

    def map(self, fn: Callable, items: list, *args, progress=None) -> list:
        results, _ = self._run(fn, items, args, reduce=False, progress=progress)
        return results

    def map_reduce(self, fn: Callable, items: list, *args, progress=None):
        return self._run(fn, items, args, reduce=True, progress=progress)

    def _run(self, fn, items, args, reduce: bool, progress):
        from distributed import as_completed

        shared = [self.client.scatter(a, broadcast=True) if _big(a) else a for a in args]
        leaves = self.client.map(fn, items, *[[a] * len(items) for a in shared], pure=False)
        index = {f.key: i for i, f in enumerate(leaves)}
        total = None
        if reduce:
            total = tree_shape(leaves, lambda a, b: self.client.submit(add_pair, a, b, pure=False))
            if total is not None and total in leaves:
                total = self.client.submit(add_pair, total, None, pure=False)
        results: list = [None] * len(items)
        for done, fut in enumerate(as_completed(leaves), 1):
            i = index[fut.key]
            results[i] = fut.result()
            # the client lets go of the leaf: its data lives on only until its pair sum has run
            leaves[i] = None
            if progress:
                progress(done, len(items))
        summed = summable(total.result()) if total is not None else None
        return results, summed

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def _workers(address: str) -> int:
    if ":" not in address:
        return os.cpu_count() or 1
    text = address.split(":", 1)[1]
    if not text.isdigit() or int(text) < 1:
        raise CliError(
            f"--dask {address}: give local, local:N (N workers, at least 1) or tcp://HOST:PORT"
        )
    return int(text)


def _warm_up() -> None:
    import importlib

    for name in ("forcemap.host.season.tasks", "pyarrow.parquet"):
        with contextlib.suppress(ImportError):
            importlib.import_module(name)
    from forcemap.host.season.tasks import roomy_heap

    roomy_heap()


def _big(obj: Any) -> bool:
    return hasattr(obj, "total")


def runner(address: str | None):
    """`--dask ADDRESS` to a runner (None: this process)."""
    return LocalRunner() if not address else DaskRunner(address)
