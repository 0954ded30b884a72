"""Bayesian linear regression from sufficient statistics: the design's feature blocks and Gram matrices (with
per-fold Gram matrices for cross-validation by downdates), and the log marginal likelihood with its analytic
gradient by the log prior variances and the log noise variance. The numerical core of `model.Model`."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
from collections.abc import Iterator

import numpy as np
from forcemap.host.workbench.engine import fourier
from forcemap.host.workbench.engine.design_cache import DesignCache, design_key  # noqa: F401 - part of this API
from forcemap.host.workbench.engine.threads import blas_threads, small_blas  # noqa: F401 - part of this API
from scipy import linalg

LOG_2PI = math.log(2 * math.pi)


# rows per chunk when features are computed on demand: 4096 x 2048 features are 64 MB
CHUNK_ROWS = 4096
# a fast GP block's products with up to this many other columns come from sine tables (beyond: features)
SINE_COLS = 8
# with finufft (`nufft`): up to this many
NUFFT_COLS = 160
# a product over at most this many rows comes from their features: a non-uniform FFT's fixed cost (its plan and
# the FFT of the oversampled grid, about a millisecond) is worth hundreds of rows' features (the folds' cells)
FEW_ROWS = 256
# a design with features below this size holds them; a larger one computes them chunk by chunk when needed
DENSE_BYTES = 160 * 2**20


def chunks(rows: np.ndarray, size: int | None = None) -> Iterator[np.ndarray]:
    size = size or CHUNK_ROWS
    for a in range(0, len(rows), size):
        yield rows[a : a + size]


def _zero_outside(rows, r: np.ndarray) -> np.ndarray | None:
    """`r` with zeros outside `rows` (every row, or a mask of at least a tenth of them: fewer are cheaper
    gathered); None for other rows."""
    if isinstance(rows, slice) and rows == slice(None):
        return r
    rows = np.asarray(rows)
    if rows.dtype == bool and len(rows) == len(r) and 10 * np.count_nonzero(rows) >= len(rows):
        return np.where(rows, r, 0.0)
    return None


def as_rows(rows, n: int) -> np.ndarray:
    """Row indices from a boolean mask, a slice or indices."""
    if isinstance(rows, slice):
        return np.arange(n)[rows]
    rows = np.asarray(rows)
    return np.flatnonzero(rows) if rows.dtype == bool else rows


class TermBlock:
    """A feature term's block, computed from its inputs for the rows asked for: a design of 43,000 rows and
    2,048 basis functions never holds its 0.7 GB of features."""

    def __init__(self, term, Z: np.ndarray) -> None:
        self.term, self.Z = term, Z
        self.shape = (len(Z), term.features(Z[:1]).shape[1])

    def __getitem__(self, rows) -> np.ndarray:
        return self.term.features(self.Z[rows])


class Design:
    """Feature blocks of the training data (arrays, or `TermBlock`s computed chunk by chunk when large) with
    their Gram matrix, computed on first use, and cached per-fold Gram matrices. With `plan` (a fold
    assignment) the Gram matrix is the sum of that assignment's fold Grams, accumulated in the same pass.
    `fast` = (block index, term, inputs) of a reduced-rank GP block whose own Gram comes from `fourier`'s
    cosine tables: only its cross products with the other (small) blocks need the features."""

    def __init__(
        self, blocks: list, plan: np.ndarray | None = None, fast: tuple | None = None
    ) -> None:
        self.blocks = blocks
        self.sizes = [b.shape[1] for b in blocks]
        self.plan = plan
        self.fast = fast
        self._folds: dict[str, list[np.ndarray]] = {}
        self._fold_ids: dict[str, np.ndarray] = {}

    @classmethod
    def from_stats(cls, G: np.ndarray, n: int, sizes: list[int]) -> Design:
        """A design known only by its Gram matrix (a fit from summed sufficient statistics): no rows."""
        d = cls([])
        d.G, d.sizes, d._n = G, list(sizes), n
        return d

    @functools.cached_property
    def G(self) -> np.ndarray:
        return self.products(None)[0]

    @property
    def fast_cols(self) -> tuple[slice, np.ndarray]:
        """Columns of the fast block (a slice), and of every other block (indices)."""
        start = sum(self.sizes[: self.fast[0]])
        stop = start + self.sizes[self.fast[0]]
        cols = np.arange(self.M)
        return slice(start, stop), np.concatenate([cols[:start], cols[stop:]])

    def _pass(self, rows, r: np.ndarray | None, want_gram: bool):
        """Phi'Phi (if `want_gram`) and Phi'r (if `r`) over `rows`, in one pass over their features."""
        if self._sines_pay(r is not None):
            return self._fast_pass(rows, r, want_gram)
        G = np.zeros((self.M, self.M)) if want_gram and self.fast is None else None
        b = None if r is None else np.zeros(self.M)
        fast = self.fast if want_gram else None
        if fast is not None:
            fcols, slow = self.fast_cols
            cross = np.zeros((self.M, len(slow)))
        if G is not None or b is not None or (fast is not None and len(slow)):
            with blas_threads(None):
                for idx, F in self.row_chunks(rows):
                    if G is not None:
                        G += F.T @ F
                    elif fast is not None:
                        cross += F.T @ F[:, slow]
                    if b is not None:
                        b += F.T @ r[idx]
        if fast is not None:
            G = np.zeros((self.M, self.M))
            G[:, slow], G[slow, :] = cross, cross.T
            Z = fast[2][as_rows(rows, self.n)]
            G[fcols, fcols] = fourier.gram(fast[1], Z)
        return G, b

    def _sines_pay(self, extra: int) -> bool:
        """The fast block's products with the other columns (and `extra` more) from sine tables: a few columns,
        or any covariate's with finufft (O(n w^D) a column, where the features cost O(n M))."""
        limit = NUFFT_COLS if fourier.nufft.available() else SINE_COLS
        return self.fast is not None and self.M - self.sizes[self.fast[0]] + extra <= limit

    def _fast_pass(self, rows, r: np.ndarray | None, want_gram: bool):
        """`_pass` without the fast block's features: its Gram matrix from cosine tables, its products with
        the other blocks' few columns and with `r` from sine tables (`fourier.transpose_products`)."""
        i, term, Zall = self.fast
        idx = as_rows(rows, self.n)
        fcols, slow = self.fast_cols
        others = [b[idx] for k, b in enumerate(self.blocks) if k != i]
        S = np.hstack([np.zeros((len(idx), 0)), *others])
        cols = ([S] if want_gram else []) + ([] if r is None else [r[idx][:, None]])
        Z = Zall[idx]
        Ft = fourier.transpose_products(term, Z, np.hstack(cols)) if cols else None
        G = b = None
        if want_gram:
            G = np.zeros((self.M, self.M))
            G[fcols, fcols] = fourier.gram(term, Z)
            G[fcols, slow], G[slow, fcols] = Ft[:, : len(slow)], Ft[:, : len(slow)].T
            G[np.ix_(slow, slow)] = S.T @ S
        if r is not None:
            b = np.zeros(self.M)
            b[fcols], b[slow] = Ft[:, -1], S.T @ r[idx]
        return G, b

    def products(self, r: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None, list | None]:
        """G, Phi'r and Phi_f'r_f for every fold f of `plan` (None without `r` or without a plan), in one pass
        over the data that also accumulates the Gram matrix (and the plan's fold Grams) if not known yet."""
        plan = self.plan if self.plan is not None and len(self.plan) == self.n else None
        known = "G" in self.__dict__
        if known and (r is None or plan is None):
            return self.G, None if r is None else self.rmatvec(r), None
        parts = [slice(None)] if plan is None else [plan == f for f in np.unique(plan)]
        grams, bs = zip(*(self._pass(rows, r, not known) for rows in parts), strict=True)
        if not known:
            self.G = grams[0] if plan is None else np.sum(grams, axis=0)
            if plan is not None:
                key = folds_key(plan)
                self._folds[key], self._fold_ids[key] = list(grams), plan
        if r is None:
            return self.G, None, None
        return self.G, np.sum(bs, axis=0), (None if plan is None else list(bs))

    def gram(self, rows) -> np.ndarray:
        """Phi'Phi over `rows`."""
        return self._pass(rows, None, True)[0]

    @property
    def n(self) -> int:
        return self.blocks[0].shape[0] if self.blocks else self._n

    @property
    def M(self) -> int:
        return sum(self.sizes)

    @property
    def lazy(self) -> bool:
        return any(isinstance(b, TermBlock) for b in self.blocks)

    def _materialize(self) -> None:
        """Hold the features once they are needed, if they are small."""
        if self.lazy and self.n * self.M * 8 <= DENSE_BYTES:
            self.blocks = [b[:] if isinstance(b, TermBlock) else b for b in self.blocks]

    def rows(self, rows, hold: bool = True) -> np.ndarray:
        """The features of `rows`, column-major; with `hold=False` a lazy design computes only theirs (a few
        rows' products need not make it hold all of its own)."""
        if hold:
            self._materialize()
        idx = as_rows(rows, self.n)
        out = np.empty((self.M, len(idx)))
        i = 0
        for b, m in zip(self.blocks, self.sizes, strict=True):
            if isinstance(b, np.ndarray) and b.T.flags.c_contiguous:
                np.take(
                    b.T, idx, axis=1, out=out[i : i + m]
                )  # whole rows of the column-major block
            else:
                out[i : i + m] = b[idx].T
            i += m
        return out.T

    def row_chunks(self, rows=slice(None)) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """(row indices, their features) in chunks: one chunk for a design that holds its features."""
        self._materialize()
        idx = as_rows(rows, self.n)
        if not self.lazy:
            yield idx, self.rows(idx)
            return
        for c in chunks(idx):
            yield c, self.rows(c)

    def rmatvec(self, r: np.ndarray, rows=slice(None)) -> np.ndarray:
        """Phi[rows]' r[rows] (`r` has a value for every row)."""
        if self._sines_pay(1):
            return self._fast_pass(rows, r, False)[1]
        self._materialize()
        if not self.lazy and (w := _zero_outside(rows, r)) is not None:
            # features held: each block's product with r zeroed outside the rows, without copying the rows'
            # features out (a CV fold's fifth of 8,310 rows x 433 columns: 2.9 ms gathered, 1.1 ms so)
            return np.concatenate([b.T @ w for b in self.blocks])
        out = np.zeros(self.M)
        for idx, F in self.row_chunks(rows):
            out += F.T @ r[idx]
        return out

    def matvec(self, w: np.ndarray) -> np.ndarray:
        """Phi w."""
        return np.concatenate([F @ w for _, F in self.row_chunks()])

    def subset(self, rows) -> Design:
        """The design of some rows: holding its features when they are small, else computing them from the
        rows' inputs when needed (a million-row survey's 200,000 hyperparameter rows at 1,600 functions would
        be 2.5 GB)."""
        fast = None if self.fast is None else (*self.fast[:2], self.fast[2][rows])
        blocks = [
            TermBlock(b.term, b.Z[rows]) if isinstance(b, TermBlock) else np.asarray(b[rows])
            for b in self.blocks
        ]
        if fast is not None and isinstance(blocks[fast[0]], TermBlock):
            fast = (fast[0], blocks[fast[0]].term, blocks[fast[0]].Z)
        return Design(blocks, fast=fast)

    def augment(self, new: np.ndarray) -> Design:
        """The design with one more feature block; reuses this Gram matrix and its fold Grams."""
        d = Design(self.blocks + [new], fast=self.fast)
        cross = self.cross(slice(None), new)
        d.G = np.block([[self.G, cross], [cross.T, new.T @ new]])
        d._fold_ids = dict(self._fold_ids)
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
        cross = np.zeros((len(cells), self.M, new.shape[1]))
        gram = np.empty((len(cells), new.shape[1], new.shape[1]))
        for c in range(len(cells)):
            rows = np.flatnonzero(cell_of_row == c)
            nc = new[rows]
            cross[c] = self.cross(rows, new)
            gram[c] = nc.T @ nc
        return cells, cross, gram

    def cross(self, rows, new: np.ndarray) -> np.ndarray:
        """Phi[rows]' new[rows] (M x k): the fast block's part from sine tables when they pay (with finufft,
        O(n w^D) a column: a diagnosis's candidate costs no n x M features), the rest from the features; a few
        rows' (`FEW_ROWS`) all from their features."""
        idx = as_rows(rows, self.n)
        if len(idx) <= FEW_ROWS:
            return self.rows(idx, hold=False).T @ new[idx]
        if not self._sines_pay(new.shape[1]):
            out = np.zeros((self.M, new.shape[1]))
            for c, F in self.row_chunks(idx):
                out += F.T @ new[c]
            return out
        i, term, Zall = self.fast
        fcols, slow = self.fast_cols
        out = np.empty((self.M, new.shape[1]))
        out[fcols] = fourier.transpose_products(term, Zall[idx], new[idx])
        others = [b[idx] for k, b in enumerate(self.blocks) if k != i]
        if others:
            out[slow] = np.hstack(others).T @ new[idx]
        return out

    def fold_grams(self, folds: np.ndarray) -> list[np.ndarray]:
        key = folds_key(folds)
        if key not in self._folds:
            self._folds[key] = [self.gram(folds == f) for f in np.unique(folds)]
            self._fold_ids[key] = folds
        return self._folds[key]


def folds_key(folds: np.ndarray) -> str:
    return hashlib.sha1(np.ascontiguousarray(folds).tobytes()).hexdigest()


@dataclasses.dataclass
class SufficientStats:
    """What Bayesian linear regression in fixed features needs of the data: G = Phi'Phi, b = Phi'y,
    yy = y'y, ysum = sum(y) and n. Statistics of disjoint chunks of rows add up to those of their union."""

    G: np.ndarray
    b: np.ndarray
    yy: float
    ysum: float
    n: int

    @classmethod
    def of(cls, Phi: np.ndarray, y: np.ndarray) -> SufficientStats:
        y = np.asarray(y, float)
        return cls(Phi.T @ Phi, Phi.T @ y, float(y @ y), float(y.sum()), len(y))

    def __add__(self, other: SufficientStats) -> SufficientStats:
        return SufficientStats(
            self.G + other.G,
            self.b + other.b,
            self.yy + other.yy,
            self.ysum + other.ysum,
            self.n + other.n,
        )


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
    # in place (B' is the Fortran-ordered B), the upper triangle cleared: no M x M copy, no mask after dtrtri
    L, info = linalg.lapack.dpotrf(B.T, lower=1, clean=1, overwrite_a=1)
    if info != 0:
        raise np.linalg.LinAlgError("dpotrf failed: the matrix is not positive definite")
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
    dBinv = np.einsum("ij,ij->j", Linv, Linv)
    # mu^2 / lam, written so that a prior variance that underflows to 0 (an RBF's far frequencies) is no 0 / 0
    g_lam = 0.5 * ((alpha / sn2) ** 2 + dBinv - 1.0)
    resid2 = rr - 2.0 * mu @ b + mu @ G @ mu
    g_sn2 = 0.5 * (-n + resid2 / sn2 + len(mu) - dBinv.sum())
    return logp, g_lam, g_sn2, post
