"""The hyperparameter search of `model.Model`: the layout of the parameter vector ([log noise] + the feature
terms' log-hyperparameters + the mean terms' parameters), its bounds and start, the negative log marginal
likelihood with its gradient, L-BFGS from the best of a few lengthscales, and the basis grown while the
lengthscale sits at the resolvable limit. The rows whose likelihood sets the hyperparameters (`spaced_rows`)."""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping, Sequence

import numpy as np
from forcemap.host.workbench.engine import fourier
from forcemap.host.workbench.engine.evidence import SufficientStats, evidence, small_blas
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import Term
from scipy.optimize import minimize

NOISE_BOUNDS = (math.log(1e-8), math.log(10.0))
# L-BFGS stops when an iteration gains less than this fraction of |log evidence| (scipy's default: 2.2e-9).
# On a survey's ~10^4 nats that is ~10^-3 nats, far below what moves a map; it halves the iterations
FTOL = 1e-7
# a survey's hyperparameters come from samples this far apart in time (see `spaced_rows`)
HYPER_SPACING_S = 5.0
MIN_HYPER_ROWS = 300


def spaced_rows(
    t: np.ndarray, spacing_s: float, min_rows: int = MIN_HYPER_ROWS
) -> np.ndarray | None:
    """The first sample of every `spacing_s` seconds of `t` (at least `min_rows`, evenly spread; None: all).

    Along a survey line the samples are a metre apart and their errors are correlated over seconds
    (paddle-wheel inertia, gusts, the sounder's 1 Hz updates, turns). Fed every sample, the marginal
    likelihood reads that as fine spatial structure: it puts the position lengthscale at the basis's
    limit, far below the line spacing, and the map then extrapolates wildly into any area it has not
    seen. Samples `spacing_s` apart are close to independent, so their marginal likelihood sets the
    hyperparameters; the posterior (the map) uses every sample."""
    t = np.asarray(t, float)
    n = len(t)
    _, rows = np.unique(np.floor((t - t.min()) / spacing_s), return_index=True)
    if len(rows) < min_rows:
        rows = np.unique(np.linspace(0, n - 1, min(min_rows, n)).astype(int))
    return None if len(rows) >= n else np.sort(rows)


def term_inputs(term: Term, X: Mapping[str, np.ndarray]) -> np.ndarray:
    if not term.inputs:
        n = len(np.asarray(next(iter(X.values()))))
        return np.zeros((n, 0))
    cols = []
    for name in term.inputs:
        if name not in X:
            raise WorkbenchError(
                f"term {term.describe()} needs input '{name}', which is not available"
            )
        v = np.asarray(X[name], float)
        cols.append(v.reshape(len(v), -1))
    return np.hstack(cols)


class HyperSearch:
    """Mixed into `Model`: everything between the data's sufficient statistics and the fitted `theta_`."""

    def _layout(self) -> None:
        self.feat_terms_ = [t for t in self.terms_ if not t.is_mean]
        self.mean_terms_ = [t for t in self.terms_ if t.is_mean]
        self.h_slices_, i = [], 1
        for t in self.feat_terms_:
            k = len(t.hypers())
            self.h_slices_.append(slice(i, i + k))
            i += k
        self.m_slices_ = []
        for t in self.mean_terms_:
            k = len(t.theta_init())
            self.m_slices_.append(slice(i, i + k))
            i += k
        self._n_params = i

    def _bounds(self) -> list[tuple[float, float]]:
        b = [NOISE_BOUNDS]
        for t in self.feat_terms_:
            b += [(h.lo, h.hi) for h in t.hypers()]
        for t in self.mean_terms_:
            b += t.theta_bounds()
        return b

    def _clip(self, theta: np.ndarray) -> np.ndarray:
        bounds = self._bounds()
        return np.clip(theta, [b[0] for b in bounds], [b[1] for b in bounds])

    def _init(self, y: np.ndarray) -> np.ndarray:
        theta = [math.log(0.1)]
        for t in self.feat_terms_:
            hs = t.hypers()
            vals = [h.init for h in hs]
            if t.is_constant:
                vals[0] = math.log((np.mean(y) / self.y_scale_) ** 2 + 1.0)
            theta += vals
        for t in self.mean_terms_:
            theta += list(t.theta_init())
        return np.array(theta, float)

    def _loglam(self, theta: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        logs, ders = [], []
        for t, sl in zip(self.feat_terms_, self.h_slices_, strict=True):
            lv, d = t.log_prior_var(theta[sl])
            logs.append(lv)
            ders.append(d)
        return np.concatenate(logs), ders

    def _mean(self, Zs: list[np.ndarray], theta: np.ndarray) -> np.ndarray:
        out = np.zeros(len(Zs[0]) if Zs else 0)
        for t, sl, Z in zip(self.mean_terms_, self.m_slices_, Zs, strict=True):
            out = out + t.mean(Z, theta[sl])
        return out

    def _objective(self, theta: np.ndarray, grad: bool = True) -> tuple[float, np.ndarray | None]:
        """Negative log marginal likelihood of the hyperparameter rows, and its gradient (None when not
        `grad`: the value alone spares the triangular inverse, as much work again as the Cholesky)."""
        loglam, ders = self._loglam(theta)
        hd = self._hdesign
        if self.mean_terms_:
            r = (self._hy - self._mean(self._hZmean, theta)) / self.y_scale_
            b, rr = hd.rmatvec(r), float(r @ r)
        else:
            r, b, rr = None, self._hb, self._hrr
        try:
            logp, g_lam, g_sn2, post = evidence(hd.G, b, rr, hd.n, loglam, theta[0], grad=grad)
        except (np.linalg.LinAlgError, ValueError):
            return 1e25, np.zeros_like(theta) if grad else None
        if not grad:
            return (-logp if np.isfinite(logp) else 1e25), None
        grad = np.zeros_like(theta)
        grad[0] = g_sn2
        i = 0
        for sl, d in zip(self.h_slices_, ders, strict=True):
            m = d.shape[0]
            grad[sl] = g_lam[i : i + m] @ d
            i += m
        if self.mean_terms_:
            self._mean_gradient(theta, r, hd.matvec(post["mu"]), post["sn2"], grad)
        if not np.isfinite(logp) or not np.all(np.isfinite(grad)):
            return 1e25, np.zeros_like(theta)
        return -logp, -grad

    def _mean_gradient(self, theta, r, fitted, sn2, grad) -> None:
        """The log evidence's gradient by the mean terms' parameters (into `grad`): the mean function's
        derivative by forward finite differences, times the posterior residual."""
        sinv_r = (r - fitted) / sn2
        for t, sl, Z in zip(self.mean_terms_, self.m_slices_, self._hZmean, strict=True):
            th = theta[sl]
            base = t.mean(Z, th)
            for k in range(len(th)):
                step = 1e-6 * max(1.0, abs(th[k]))
                th2 = th.copy()
                th2[k] += step
                dm = (t.mean(Z, th2) - base) / step / self.y_scale_
                grad[sl.start + k] = sinv_r @ dm

    def _search_lengthscale(self, theta: np.ndarray) -> np.ndarray:
        """Start L-BFGS from the best of a few lengthscales for the first GP term (avoids poor local optima)."""
        for t, sl in zip(self.feat_terms_, self.h_slices_, strict=True):
            if t.grows_basis:
                lo, hi = math.log(t.l_min * 1.1), math.log(2.0 * float(t.half.max()))
                best, best_val = theta, self._objective(theta, grad=False)[0]
                for logl in np.linspace(lo, hi, 7):
                    trial = theta.copy()
                    trial[sl.start + t.hyper_index("lengthscale")] = logl
                    val = self._objective(trial, grad=False)[0]
                    if val < best_val:
                        best, best_val = trial, val
                return best
        return theta

    def _optimize(self, theta: np.ndarray, search: bool) -> np.ndarray:
        with small_blas():
            if search:
                theta = self._search_lengthscale(theta)
            res = minimize(
                self._objective,
                theta,
                jac=True,
                method="L-BFGS-B",
                bounds=self._bounds(),
                options={"maxiter": self.max_iter, "ftol": FTOL},
            )
        self.n_iter_ = int(res.nit)
        return res.x

    def _grow_basis(
        self, X: Mapping[str, np.ndarray], y: np.ndarray, theta: np.ndarray
    ) -> np.ndarray:
        """The basis resolves lengthscales down to l_min: while the optimum sits there, double the highest
        frequency (2^D times the functions) and resume the fit."""
        for _ in range(3):
            grow = [
                t
                for t, sl in zip(self.feat_terms_, self.h_slices_, strict=True)
                if t.grows_basis
                and theta[sl.start + t.hyper_index("lengthscale")] < math.log(1.25 * t.l_min)
                and t.n_basis < min(t.max_basis, len(y))
            ]
            if not grow:
                break
            for t in grow:
                # never more basis functions than samples: there an exact GP would be cheaper
                t.n_basis = min(2**t.dims * t.n_basis, t.max_basis, max(len(y), t.n_basis))
            self._prepare(X, y, None)
            theta = self._optimize(self._clip(theta), search=False)
        return theta

    def fit_stats(self, stats: SufficientStats) -> HyperSearch:
        """Fit the hyperparameters and the posterior from sufficient statistics (`basis_stats`, summed over
        any number of chunks of rows, surveys or workers) of features of a fixed basis: `terms` are Term
        objects already set up (see `fixed_basis`), feature terms only. The basis is not grown; `predict` and
        `params_` work, cross-validation needs the rows (`fit`)."""
        from forcemap.host.workbench.engine.evidence import Design

        self.terms_ = self._build_terms()
        if any(t.is_mean for t in self.terms_):
            raise WorkbenchError("fit_stats takes feature terms only (a mean term needs the rows)")
        n, mean = stats.n, stats.ysum / stats.n
        self.y_scale_ = math.sqrt(max(stats.yy / n - mean**2, 0.0)) or 1.0
        self._layout()
        theta = self._init(np.array([mean])) if self.init is None else np.asarray(self.init, float)
        theta = self._clip(theta)
        sizes = [
            len(t.log_prior_var(theta[sl])[0])
            for t, sl in zip(self.feat_terms_, self.h_slices_, strict=True)
        ]
        self.design_ = Design.from_stats(stats.G, n, sizes)
        k = 1.0 / self.y_scale_
        self._hdesign, self._hb, self._hrr = self.design_, stats.b * k, stats.yy * k * k
        self._hy, self._hZmean = None, []
        if self.optimize:
            theta = self._optimize(theta, search=self.init is None)
        loglam, _ = self._loglam(theta)
        logp, _, _, post = evidence(stats.G, self._hb, self._hrr, n, loglam, theta[0], grad=False)
        self.theta_, self.loglam_, self.posterior_ = theta, loglam, post
        self.log_marginal_likelihood_ = float(logp)
        self.feature_residual_ = self._hb
        del self._hdesign, self._hy, self._hZmean, self._hb, self._hrr
        return self


def fixed_basis(terms: Sequence, X: Mapping[str, np.ndarray]) -> list[Term]:
    """Feature terms set up on `X` (for a season: the positions of every survey, or its bounding box): the
    basis that chunks of rows share, so that their `basis_stats` add up."""
    from forcemap.host.workbench.survey.table import is_circular
    from forcemap.host.workbench.terms.registry import build_term, parse_term

    out = []
    for t in terms:
        if isinstance(t, str):
            t = parse_term(t, is_circular)
        t = build_term(t, is_circular) if not isinstance(t, Term) else copy.deepcopy(t)
        t.setup(term_inputs(t, X))
        out.append(t)
    return out


def basis_stats(
    terms: Sequence[Term], X: Mapping[str, np.ndarray], y: np.ndarray
) -> SufficientStats:
    """(G, b, yy, ysum, n) of the features of set-up `terms` on the rows of `X`, `y`: summable across chunks.
    A reduced-rank GP's Gram comes from cosine tables (O(n P Q), not O(n M^2)); the features are computed
    chunk by chunk, never held."""
    from forcemap.host.workbench.engine.evidence import Design, TermBlock

    blocks = [TermBlock(t, term_inputs(t, X)) for t in terms]
    fast = [i for i, b in enumerate(blocks) if fourier.is_fast(b.term)]
    i = max(fast, key=lambda i: blocks[i].shape[1]) if fast else None
    design = Design(blocks, fast=None if i is None else (i, blocks[i].term, blocks[i].Z))
    y = np.asarray(y, float)
    G, b, _ = design.products(y)
    return SufficientStats(G, b, float(y @ y), float(y.sum()), len(y))
