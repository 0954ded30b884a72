"""How many BLAS threads the workbench's linear algebra runs on: one for the many small factorizations, all for
the large products (threadpoolctl; without it, whatever BLAS chose)."""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator


@functools.lru_cache(maxsize=1)
def _blas_controller():
    """threadpoolctl's BLAS libraries, found once (`threadpool_limits` reads /proc/self/maps every call)."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    return ThreadpoolController()


@contextlib.contextmanager
def blas_threads(n: int | None) -> Iterator[None]:
    """Limit BLAS threads (None: no limit). Without threadpoolctl this is a no-op."""
    ctl = _blas_controller() if n is not None else None
    with ctl.limit(limits=n, user_api="blas") if ctl else contextlib.nullcontext():
        yield


def small_blas():
    """One BLAS thread for the many small (M x M) factorizations: threads only add overhead there, and a lot
    of it on a busy 2-core machine."""
    return blas_threads(1)
