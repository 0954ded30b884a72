"""Exponential sums of weights at non-uniform points on an equispaced frequency grid, by a type-1 non-uniform FFT.

A reduced-rank GP block's Gram matrix and its products with a few other columns are gathers from the tables
sum_i w_i cos(p u_i) cos(q v_i) and sum_i w_i sin(a u_i) sin(b v_i) (`fourier`), and both are the real parts
of sums of two entries of F[k1, k2] = sum_i w_i exp(i (k1 u_i + k2 v_i)), k_d = -K_d .. K_d. With `finufft`
(the `[nufft]` extra; EFGP: Greengard, Rachh, Barnett et al. 2023) F costs O(n w^D + K log K) per weight
vector (w about 16 points per axis at the tolerance below) in place of the direct O(n K_1 K_2): n enters once
and linearly. Without it, `fourier` sums the tables directly: the same numbers to rounding.

The tolerance is finufft's tightest that it keeps in double precision: on the benchmark survey the Gram
matrix equals the direct one to 1e-15 of its largest entry. One thread, so that a sum does not depend on how
finufft splits the points (the results are the same on one and two Dask workers, run after run).
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator

import numpy as np

EPS = 1e-14


@functools.lru_cache(maxsize=1)
def _finufft():
    try:
        import finufft
    except ImportError:
        return None
    return finufft


_direct = False


def available() -> bool:
    """Whether the fast sums are at hand (the `nufft` extra) and not turned off by `direct()`."""
    return not _direct and _finufft() is not None


@contextlib.contextmanager
def direct() -> Iterator[None]:
    """Sum the tables directly inside the block, as without finufft (tests and the bench compare the two)."""
    global _direct
    before, _direct = _direct, True
    try:
        yield
    finally:
        _direct = before


def _points(angles: list[np.ndarray]) -> list[np.ndarray]:
    """The angles as finufft takes them (in [-3 pi, 3 pi)): a point far outside the GP's box (a map cell beyond
    it) taken modulo 2 pi, which the integer frequencies do not see."""
    out = []
    for a in angles:
        a = np.ascontiguousarray(a, dtype=float)
        if len(a) and np.abs(a).max() >= 3.0 * np.pi:
            a = np.mod(a, 2.0 * np.pi)
        out.append(a)
    return out


def exponential_sums(angles: list[np.ndarray], W: np.ndarray, tops: list[int]) -> np.ndarray:
    """F[c, k_1 + K_1, (k_2 + K_2)] = sum_i W[i, c] exp(i sum_d k_d u_di) for k_d = -K_d .. K_d (K_d = `tops`),
    at the points `angles` (one array per axis, each in [0, 2 pi)); (k, 2 K_1 + 1[, 2 K_2 + 1]) complex.
    Raises RuntimeError without finufft."""
    lib = _finufft()
    if lib is None:
        raise RuntimeError("finufft is not installed")
    W = np.asarray(W, float).reshape(len(angles[0]), -1)
    k = W.shape[1]
    modes = tuple(2 * t + 1 for t in tops)
    if len(angles[0]) == 0 or k == 0:
        return np.zeros((k, *modes), complex)
    c = np.ascontiguousarray(W.T, dtype=complex)
    plan = lib.Plan(1, modes, n_trans=k, eps=EPS, isign=1, nthreads=1, modeord=0)
    plan.setpts(*_points(angles))
    out = plan.execute(c if k > 1 else c[0])
    return out.reshape(k, *modes)


def exponential_values(angles: list[np.ndarray], coeffs: np.ndarray, tops: list[int]) -> np.ndarray:
    """sum_k coeffs[c, k_1 + K_1, (k_2 + K_2)] exp(i sum_d k_d u_di) at the points `angles`, (n, k) complex: a
    type-2 non-uniform FFT (the transpose of `exponential_sums`), O(n w^D + K log K) per column."""
    lib = _finufft()
    if lib is None:
        raise RuntimeError("finufft is not installed")
    modes = tuple(2 * t + 1 for t in tops)
    coeffs = np.ascontiguousarray(np.asarray(coeffs, complex).reshape(-1, *modes))
    k, n = len(coeffs), len(angles[0])
    if n == 0 or k == 0:
        return np.zeros((n, k), complex)
    plan = lib.Plan(2, modes, n_trans=k, eps=EPS, isign=1, nthreads=1, modeord=0)
    plan.setpts(*_points(angles))
    out = plan.execute(coeffs if k > 1 else coeffs[0])
    return out.reshape(k, n).T
