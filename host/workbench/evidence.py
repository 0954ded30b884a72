"""Bayesian linear regression from sufficient statistics: the design's feature blocks and Gram matrices (with
per-fold Gram matrices for cross-validation by downdates), and the log marginal likelihood with its analytic
gradient by the log prior variances and the log noise variance. The numerical core of `model.Model`."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import math
from collections.abc import Iterator

import numpy as np
from scipy import linalg

LOG_2PI = math.log(2 * math.pi)


@contextlib.contextmanager
def blas_threads(n: int | None) -> Iterator[None]:
    """Limit BLAS threads (None: no limit). Without threadpoolctl this is a no-op."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        yield
        return
    with threadpool_limits(limits=n, user_api="blas"):
        yield


def small_blas():
    """One BLAS thread for the many small (M x M) factorizations: threads only add overhead there, and a lot
    of it on a busy 2-core machine."""
    return blas_threads(1)


class Design:
    """Feature blocks of the training data with their Gram matrix, and cached per-fold Gram matrices."""

    def __init__(self, blocks: list[np.ndarray]) -> None:
        self.blocks = blocks
        self.sizes = [b.shape[1] for b in blocks]
        with blas_threads(None):
            self.G = (
                np.vstack([np.hstack([a.T @ b for b in blocks]) for a in blocks])
                if blocks
                else np.zeros((0, 0))
            )
        self._folds: dict[str, list[np.ndarray]] = {}
        self._fold_ids: dict[str, np.ndarray] = {}

    @property
    def n(self) -> int:
        return self.blocks[0].shape[0]

    @property
    def M(self) -> int:
        return sum(self.sizes)

    def rmatvec(self, r: np.ndarray, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        return np.concatenate([b[rows].T @ r for b in self.blocks])

    def matvec(self, w: np.ndarray, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        out, i = 0.0, 0
        for b, m in zip(self.blocks, self.sizes, strict=True):
            out = out + b[rows] @ w[i : i + m]
            i += m
        return out

    def rows(self, rows: np.ndarray) -> np.ndarray:
        return np.hstack([b[rows] for b in self.blocks])

    def augment(self, new: np.ndarray) -> Design:
        """The design with one more feature block; reuses this Gram matrix and its fold Grams."""
        d = Design.__new__(Design)
        d.blocks, d.sizes = self.blocks + [new], self.sizes + [new.shape[1]]
        cross = np.vstack([b.T @ new for b in self.blocks])
        d.G = np.block([[self.G, cross], [cross.T, new.T @ new]])
        d._folds, d._fold_ids = {}, dict(self._fold_ids)
        if not self._folds:
            return d
        cells, cell_cross, cell_gram = self._cell_products(new)
        for j, (key, grams) in enumerate(self._folds.items()):
            d._folds[key] = []
            for f, Gf in zip(np.unique(self._fold_ids[key]), grams, strict=True):
                inside = cells[:, j] == f
                cf, nn = cell_cross[inside].sum(axis=0), cell_gram[inside].sum(axis=0)
                d._folds[key].append(np.block([[Gf, cf], [cf.T, nn]]))
        return d

    def _cell_products(self, new: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The cross products of the design and of `new` with `new` over the cells of the cached fold
        assignments (rows that share a fold in every one): a pass over the data once, not once per assignment.
        Returns each cell's fold in every assignment (columns in the order of `_folds`), and its products."""
        ids = np.stack([self._fold_ids[key] for key in self._folds], axis=1)
        cells, cell_of_row = np.unique(ids, axis=0, return_inverse=True)
        cell_of_row = cell_of_row.ravel()
        cross = np.empty((len(cells), self.M, new.shape[1]))
        gram = np.empty((len(cells), new.shape[1], new.shape[1]))
        for c in range(len(cells)):
            rows = cell_of_row == c
            nc = new[rows]
            cross[c] = np.vstack([b[rows].T @ nc for b in self.blocks])
            gram[c] = nc.T @ nc
        return cells, cross, gram

    def fold_grams(self, folds: np.ndarray) -> list[np.ndarray]:
        key = hashlib.sha1(np.ascontiguousarray(folds).tobytes()).hexdigest()
        if key not in self._folds:
            grams = []
            for f in np.unique(folds):
                X = self.rows(folds == f)
                grams.append(X.T @ X)
            self._folds[key] = grams
            self._fold_ids[key] = folds
        return self._folds[key]


@functools.lru_cache(maxsize=4)
def _upper_mask(m: int) -> np.ndarray:
    return np.triu(np.ones((m, m), bool), 1)


def evidence(G, b, rr, n, loglam, logsn2, grad=True):
    """Log marginal likelihood of y = Phi w + e, w ~ N(0, diag(lam)), e ~ N(0, sn2 I) from the statistics
    G = Phi'Phi, b = Phi'y, rr = y'y; with its gradient by log(lam) and log(sn2), and the posterior."""
    lam = np.exp(loglam)
    s = np.sqrt(lam)
    sn2 = math.exp(logsn2)
    # diag(s) G diag(s) / sn2 + I, in place: the broadcast product with temporaries cost more than the Cholesky
    t = s / math.sqrt(sn2)
    B = G * t[:, None]
    B *= t
    B.flat[:: len(B) + 1] += 1.0
    L, _ = linalg.cho_factor(B, lower=True, check_finite=False)
    c = s * b
    alpha = linalg.cho_solve((L, True), c, check_finite=False)
    quad = (rr - c @ alpha / sn2) / sn2
    logdet = n * logsn2 + 2.0 * np.log(np.diag(L)).sum()
    logp = -0.5 * (quad + logdet + n * LOG_2PI)
    mu = s * alpha / sn2
    post = {"L": L, "s": s, "mu": mu, "sn2": sn2}
    if not grad:
        return logp, None, None, post
    # diag(B^-1) = column sums of squares of L^-1: one triangular inverse, half the work of dpotri
    Linv, info = linalg.lapack.dtrtri(L, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError("dtrtri failed")
    Linv[_upper_mask(len(Linv))] = 0.0
    dBinv = np.einsum("ij,ij->j", Linv, Linv)
    g_lam = 0.5 * (mu**2 / lam + dBinv - 1.0)
    resid2 = rr - 2.0 * mu @ b + mu @ G @ mu
    g_sn2 = 0.5 * (-n + resid2 / sn2 + len(mu) - dBinv.sum())
    return logp, g_lam, g_sn2, post
