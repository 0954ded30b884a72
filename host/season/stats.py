"""Sufficient statistics of a reduced-rank GP for a fixed basis, and the fit of its hyperparameters from them.

This is the season's one interface to the estimator (`workbench.evidence`): for a fixed basis the Gram matrix
Phi'Phi, the products Phi'Y and Y'Y do not depend on the hyperparameters, so statistics computed per chunk
and summed in any order give what one pass over all the data would; the hyperparameters are then fitted on
the summed m x m matrices alone (L-BFGS on the log marginal likelihood with its analytic gradient). When
the workbench gains its own public per-chunk statistics, only this module changes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from forcemap.host.workbench.engine import fourier
from forcemap.host.workbench.engine.evidence import LOG_2PI, small_blas
from forcemap.host.workbench.engine.model import FTOL, NOISE_BOUNDS
from scipy import linalg
from scipy.optimize import minimize

CHUNK_ROWS = 8192


@dataclass
class Stats:
    """G = Phi'Phi (m x m), B = Phi'Y (m x k), R = Y'Y (k x k), n rows: summable over any split of rows."""

    G: np.ndarray
    B: np.ndarray
    R: np.ndarray
    n: int

    def __add__(self, other: Stats) -> Stats:
        return Stats(self.G + other.G, self.B + other.B, self.R + other.R, self.n + other.n)

    def scaled(self, s: float) -> Stats:
        """The statistics of the targets times `s` against features times `s` (a survey's scale)."""
        return Stats(self.G * s * s, self.B * s, self.R, self.n)

    @property
    def nbytes(self) -> int:
        return self.G.nbytes + self.B.nbytes + self.R.nbytes


class ConstAndGP:
    """The features [1, gp(Z)] of a season's map: a constant and a reduced-rank GP (`workbench.terms`)."""

    def __init__(self, gp) -> None:
        self.gp = gp

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        return np.hstack([np.ones((len(Z), 1)), self.gp.features(Z)])


def fast_gp(features, Z: np.ndarray):
    """The GP of `ConstAndGP` features when its statistics come from the NUFFT tables, else None."""
    gp = getattr(features, "gp", None)
    return gp if gp is not None and fourier.is_fast(gp) and len(Z) else None


def chunk_stats(features, Z: np.ndarray, Y: np.ndarray, rows: int = CHUNK_ROWS) -> Stats:
    """The statistics of targets Y (n x k) against `features(Z)`, streamed over row chunks (never n x m at
    once beyond `rows` rows); for `ConstAndGP` features with a basis large enough, from the GP's cosine and
    sine tables instead (`workbench.fourier`: non-uniform FFTs with finufft, O(n) not O(n m^2), the same
    numbers to rounding)."""
    gp = fast_gp(features, Z)
    if gp is not None:
        Y = np.asarray(Y, float).reshape(len(Z), -1)
        G = np.empty((gp.J.shape[0] + 1,) * 2)
        cross = fourier.transpose_products(gp, Z, np.hstack([np.ones((len(Z), 1)), Y]))
        G[0, 0], G[0, 1:], G[1:, 0] = len(Z), cross[:, 0], cross[:, 0]
        G[1:, 1:] = fourier.gram(gp, Z)
        B = np.vstack([Y.sum(axis=0), cross[:, 1:]])
        return Stats(G, B, Y.T @ Y, len(Z))
    out = None
    for a in range(0, len(Z), rows):
        Phi = features(Z[a : a + rows])
        y = Y[a : a + rows]
        part = Stats(Phi.T @ Phi, Phi.T @ y, y.T @ y, len(y))
        out = part if out is None else out + part
    if out is None:
        m = features(Z[:1]).shape[1] if len(Z) else 0
        k = Y.shape[1]
        return Stats(np.zeros((m, m)), np.zeros((m, k)), np.zeros((k, k)), 0)
    return out


def masked_stats(
    features, Z: np.ndarray, targets: dict[str, tuple[np.ndarray, np.ndarray]], rows: int = CHUNK_ROWS
) -> dict[str, Stats]:
    """The statistics of each named target (Y, n x k, and the rows that have it) on its own rows, in one
    pass: the features once per chunk, one Gram matrix per chunk, each target's from it less the few
    rows it lacks (or from its own rows, when it lacks most). With the GP's fast tables (`chunk_stats`),
    one NUFFT pass per set of targets that share their rows."""
    if fast_gp(features, Z) is not None:
        return shared_rows_stats(features, Z, targets)
    out: dict[str, Stats] = {}
    for a in range(0, len(Z), rows):
        Phi, G = features(Z[a : a + rows]), None
        for name, (Y, ok) in targets.items():
            m, y = ok[a : a + rows], Y[a : a + rows]
            if m.all() or (~m).sum() < m.sum():
                G = Phi.T @ Phi if G is None else G
                lack = Phi[~m]
                Gm = G - lack.T @ lack if len(lack) else G
            else:
                Gm = Phi[m].T @ Phi[m]
            ym = y if m.all() else np.where(m[:, None], y, 0.0)  # a row it lacks adds nothing
            part = Stats(Gm, Phi.T @ ym, ym.T @ ym, int(m.sum()))
            out[name] = part if name not in out else out[name] + part
    for name, (Y, _) in targets.items():
        if name not in out:  # no rows at all
            out[name] = chunk_stats(features, Z[:0], Y[:0])
    return out


def shared_rows_stats(
    features, Z: np.ndarray, targets: dict[str, tuple[np.ndarray, np.ndarray]]
) -> dict[str, Stats]:
    """Each target's statistics on its own rows by `chunk_stats`, the targets that have the same rows
    stacked into one call (one Gram matrix for them)."""
    groups: dict[bytes, list[str]] = {}
    for name, (_, ok) in targets.items():
        groups.setdefault(np.packbits(ok).tobytes(), []).append(name)
    out: dict[str, Stats] = {}
    for names in groups.values():
        ok = targets[names[0]][1]
        Ys = [np.asarray(targets[n][0], float).reshape(len(Z), -1)[ok] for n in names]
        st = chunk_stats(features, Z[ok], np.hstack(Ys))
        a = 0
        for n, Y in zip(names, Ys, strict=True):
            cols = slice(a, a + Y.shape[1])
            out[n] = Stats(st.G, st.B[:, cols], st.R[cols, cols], st.n)
            a += Y.shape[1]
    return out


def tree_sum(items: list):
    """Pairwise sum, level by level (the same order as the Dask tree reduction)."""
    level = list(items)
    if not level:
        raise ValueError("nothing to sum")
    while len(level) > 1:
        nxt = [level[i] + level[i + 1] for i in range(0, len(level) - 1, 2)]
        if len(level) % 2:
            nxt.append(level[-1])
        level = nxt
    return level[0]


class Prior:
    """The prior of the weights: one const feature and a reduced-rank GP (`workbench.terms`), hyperparameters
    [log noise var, log const var, log gp var, log lengthscale] in units of the target's std."""

    def __init__(self, gp) -> None:
        from forcemap.host.workbench.terms.simple import ConstTerm

        self.const, self.gp = ConstTerm(), gp

    def bounds(self) -> list[tuple[float, float]]:
        return [NOISE_BOUNDS] + [(h.lo, h.hi) for h in self.const.hypers() + self.gp.hypers()]

    def init(self) -> np.ndarray:
        return np.array([math.log(0.1)] + [h.init for h in self.const.hypers() + self.gp.hypers()])

    def loglam(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Log prior variances of the features, and their derivative by theta[1:] (m x 3)."""
        lc, dc = self.const.log_prior_var(theta[1:2])
        lg, dg = self.gp.log_prior_var(theta[2:4])
        d = np.zeros((len(lc) + len(lg), 3))
        d[: len(lc), :1], d[len(lc) :, 1:] = dc, dg
        return np.concatenate([lc, lg]), d


def evidence_columns(G, B, rr, n, loglam, logsn2, grad: bool = True):
    """`workbench.evidence.evidence` summed over the columns of B (independent targets with the same
    features and hyperparameters): one Cholesky and one triangular inverse for all of them. Returns the log
    evidence, its gradient by log(lam) and by log(sn2) (None without `grad`: no triangular inverse), and
    the posterior means (m x k) in scaled units."""
    lam = np.exp(loglam)
    s = np.sqrt(lam)
    sn2 = math.exp(logsn2)
    m, k = B.shape
    t = s / math.sqrt(sn2)
    A = G * t[:, None]
    A *= t
    A.flat[:: m + 1] += 1.0
    # as `workbench.evidence.evidence`: in place, the upper triangle cleared (no copy, no mask after dtrtri)
    L, info = linalg.lapack.dpotrf(A.T, lower=1, clean=1, overwrite_a=1)
    if info != 0:
        raise np.linalg.LinAlgError("dpotrf failed: the matrix is not positive definite")
    C = s[:, None] * B
    alpha = linalg.cho_solve((L, True), C, check_finite=False)
    quad = (rr - np.einsum("ij,ij->j", C, alpha) / sn2) / sn2
    logdet = n * logsn2 + 2.0 * np.log(np.diag(L)).sum()
    logp = float(-0.5 * (quad.sum() + k * (logdet + n * LOG_2PI)))
    Mu = s[:, None] * alpha / sn2
    if not grad:
        return logp, None, None, Mu, (L, s, sn2)
    Linv, info = linalg.lapack.dtrtri(L, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError("dtrtri failed")
    dBinv = np.einsum("ij,ij->j", Linv, Linv)
    g_lam = 0.5 * ((Mu**2).sum(axis=1) / lam + k * (dBinv - 1.0))
    resid2 = rr - 2.0 * np.einsum("ij,ij->j", Mu, B) + np.einsum("ij,ij->j", Mu, G @ Mu)
    g_sn2 = float(0.5 * (-k * n + resid2.sum() / sn2 + k * (m - dBinv.sum())))
    return logp, g_lam, g_sn2, Mu, (L, s, sn2)


def _objective(theta, prior: Prior, G, B, rr, n):
    """Minus the summed log evidence of the columns of B, and its gradient."""
    loglam, d = prior.loglam(theta)
    try:
        logp, g_lam, g_sn2, _, _ = evidence_columns(G, B, rr, n, loglam, theta[0])
    except (np.linalg.LinAlgError, ValueError):
        return 1e25, np.zeros_like(theta)
    grad = np.concatenate([[g_sn2], g_lam @ d])
    if not np.isfinite(logp) or not np.all(np.isfinite(grad)):
        return 1e25, np.zeros_like(theta)
    return -logp, -grad


def target_scale(st: Stats) -> np.ndarray:
    """The targets' pooled std (the const feature is column 0 of the basis)."""
    mean = st.B[0] / max(st.n, 1)
    var = np.diag(st.R) / max(st.n, 1) - mean**2
    return np.sqrt(np.maximum(var, 1e-12))


def fit_hypers(prior: Prior, st: Stats, y_scale: float, theta0=None, max_iter: int = 200):
    """Type-II maximum likelihood of the hyperparameters from the statistics alone (targets / y_scale); from a
    grid of lengthscales first when there is no start."""
    B, rr = st.B / y_scale, np.diag(st.R) / y_scale**2
    bounds = prior.bounds()
    with small_blas():
        if theta0 is None:
            theta0 = prior.init()
            best = _objective(theta0, prior, st.G, B, rr, st.n)[0]
            for logl in np.linspace(bounds[3][0] + 0.1, bounds[3][1] - 0.5, 7):
                trial = theta0.copy()
                trial[3] = logl
                val = _objective(trial, prior, st.G, B, rr, st.n)[0]
                if val < best:
                    theta0, best = trial, val
        res = minimize(
            _objective,
            np.clip(theta0, [b[0] for b in bounds], [b[1] for b in bounds]),
            args=(prior, st.G, B, rr, st.n),
            jac=True,
            method="L-BFGS-B",
            bounds=bounds,
            options={"maxiter": max_iter, "ftol": FTOL},
        )
    return res.x, -float(res.fun)


@dataclass
class Posterior:
    """Gaussian posterior of the weights of every target column (units of the targets): mean (m x k), and
    the Cholesky factor of the scaled precision for the predictive std."""

    mean: np.ndarray
    L: np.ndarray
    s: np.ndarray
    sn2: float
    y_scale: float

    def predict(self, Phi: np.ndarray, return_std: bool = True):
        mu = Phi @ self.mean
        if not return_std:
            return mu, None
        V = linalg.solve_triangular(self.L, (Phi * self.s).T, lower=True, check_finite=False)
        return mu, np.sqrt(np.maximum((V**2).sum(axis=0), 0.0)) * self.y_scale


def posterior(prior: Prior, theta: np.ndarray, st: Stats, y_scale: float) -> Posterior:
    """The weights' posterior given the hyperparameters, from the statistics."""
    loglam, _ = prior.loglam(theta)
    with small_blas():
        _, _, _, Mu, (L, s, sn2) = evidence_columns(
            st.G, st.B / y_scale, np.diag(st.R) / y_scale**2, st.n, loglam, theta[0], grad=False
        )
    return Posterior(Mu * y_scale, L, s, sn2, y_scale)


def weighted_sum(stats: list[Stats], w: np.ndarray) -> Stats:
    """sum_k of the statistics of survey k with its features times w_k (in place, one pass in order)."""
    G, B = np.zeros_like(stats[0].G), np.zeros_like(stats[0].B)
    R, n, buf = np.zeros_like(stats[0].R), 0, np.empty_like(stats[0].G)
    for st, wk in zip(stats, w, strict=True):
        np.multiply(st.G, float(wk) ** 2, out=buf)
        G += buf
        B += float(wk) * st.B
        R += st.R
        n += st.n
    return Stats(G, B, R, n)


def sq_error(st: Stats, W: np.ndarray) -> float:
    """Sum over rows and target columns of (y - Phi w)^2, from the statistics: a map scored on data it never
    saw without touching the data again."""
    return float(np.trace(st.R) - 2.0 * np.sum(W * st.B) + np.sum(W * (st.G @ W)))


def without_offset(st: Stats) -> Stats:
    """The statistics with a free per-survey constant projected out of every target column (column 0 of
    the basis is the constant): the offset's flat-prior profile."""
    g, ysum, n = st.G[:, 0], st.B[0], max(st.n, 1)
    # G - g g' / n with one temporary, not three (the same roundings: the product, its quotient, the sum)
    G = np.multiply.outer(g, g)
    G /= -n
    G += st.G
    return Stats(
        G,
        st.B - np.outer(g, ysum) / n,
        st.R - np.outer(ysum, ysum) / n,
        st.n,
    )
