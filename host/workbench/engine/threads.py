"""How many BLAS threads forcemap's linear algebra runs on: the one home of that rule.

- Every forcemap process starts with one BLAS/OpenMP thread unless the user's environment says otherwise:
  `forcemap`'s entry point calls `one_thread_by_default()` before anything imports numpy, and its
  subprocesses (the demo's steps, the live map process) inherit the setting. OpenBLAS's threads spin while
  they wait, so on a busy 2-core machine its default of a thread per core fought the machine's other work:
  one demo `fit` took 5.4-6.0 s beside a loaded machine with the default threads, 3.0-3.1 s with one
  (issue 58). `OPENBLAS_NUM_THREADS=4 forcemap ...` gives the large Gram products four threads.
- The many small (M x M) factorizations always run on one (`small_blas`), whatever the process's default:
  threads only add overhead there (threadpoolctl, a base dependency, sets that limit at run time).
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Iterator

# what numpy's BLAS (OpenBLAS, MKL) and OpenMP read when they load: too late once numpy is imported
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_thread_by_default() -> None:
    """One BLAS thread for this process and its children, unless the environment already sets a count.
    Takes effect only if numpy is not loaded yet: call it first thing."""
    for var in THREAD_VARS:
        os.environ.setdefault(var, "1")


@functools.lru_cache(maxsize=1)
def _blas_controller():
    """threadpoolctl's BLAS libraries, found once (`threadpool_limits` reads /proc/self/maps every call)."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # a base dependency; kept optional for an install that lost it
        return None
    return ThreadpoolController()


@contextlib.contextmanager
def blas_threads(n: int | None) -> Iterator[None]:
    """Limit BLAS threads (None: the process's default). Without threadpoolctl this is a no-op."""
    ctl = _blas_controller() if n is not None else None
    with ctl.limit(limits=n, user_api="blas") if ctl else contextlib.nullcontext():
        yield


def small_blas():
    """One BLAS thread for the many small (M x M) factorizations: threads only add overhead there, and a lot
    of it on a busy 2-core machine."""
    return blas_threads(1)
