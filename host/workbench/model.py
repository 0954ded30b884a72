"""The estimator: a sum of terms fitted as Bayesian linear regression in their features, hyperparameters by
type-II maximum likelihood (L-BFGS on log-parameters; the gradient by the feature terms' hyperparameters and the
noise is analytic from sufficient statistics, by a mean term's parameters a finite difference).

`Model(terms).fit(X, y)` / `.predict(X, return_std=True)` / `.params_`, scikit-learn style: `__init__` stores its
arguments, `fit` works on copies of the terms, fitted state ends in `_`. `X` maps input names to arrays:
"position" -> (n, 2) metres, any covariate -> (n,).
"""

from __future__ import annotations

import copy
import inspect
import math
from collections.abc import Mapping, Sequence

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.evidence import Design, blas_threads, evidence, small_blas
from forcemap.host.workbench.spec import BASELINE, build_term, parse_term
from forcemap.host.workbench.table import is_circular
from forcemap.host.workbench.terms import ConstTerm, HilbertGPTerm, Term, TermSpec
from scipy import linalg
from scipy.optimize import minimize

NOISE_BOUNDS = (math.log(1e-8), math.log(10.0))
CHUNK = 8192
# where callers have always found them
__all__ = [
    "Design",
    "Model",
    "NotFittedError",
    "blas_threads",
    "evidence",
    "small_blas",
    "term_inputs",
]
# L-BFGS stops when an iteration gains less than this fraction of |log evidence| (scipy's default: 2.2e-9).
# On a survey's ~10^4 nats that is ~10^-3 nats, far below what moves a map; it halves the iterations
FTOL = 1e-7


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


class NotFittedError(ValueError, AttributeError):
    """The model is used before `fit` (the same bases as scikit-learn's NotFittedError)."""


class Model:
    """A sum of terms. Feature terms (GPs, linear, cosine) are Bayesian linear regression in fixed features;
    mean terms (power law, user functions) are subtracted with parameters fitted by marginal likelihood.

    `terms`: term strings, `TermSpec`s or `Term` objects (copied by `fit`, never changed). `max_basis` caps the
    basis of a spatial GP term; `hyper_rows` are the rows whose marginal likelihood sets the hyperparameters
    (None: all); the posterior always uses every row."""

    def __init__(
        self,
        terms: Sequence[Term | TermSpec | str] = tuple(BASELINE),
        max_iter: int = 300,
        max_basis: int | None = None,
        hyper_rows: np.ndarray | None = None,
    ) -> None:
        self.terms = terms
        self.max_iter = max_iter
        self.max_basis = max_basis
        self.hyper_rows = hyper_rows

    # ---- scikit-learn's parameter protocol
    @classmethod
    def _param_names(cls) -> list[str]:
        return [p for p in inspect.signature(cls.__init__).parameters if p != "self"]

    def get_params(self, deep: bool = True) -> dict:
        """The constructor's arguments, by name."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params) -> Model:
        """Change constructor arguments (takes effect at the next `fit`)."""
        valid = self._param_names()
        for name, value in params.items():
            if name not in valid:
                raise ValueError(f"invalid parameter {name!r} for Model; valid: {', '.join(valid)}")
            setattr(self, name, value)
        return self

    def __repr__(self) -> str:
        return f"Model(terms={[str(t) if isinstance(t, (str, TermSpec)) else t.describe() for t in self.terms]!r})"

    def _build_terms(self) -> list[Term]:
        """Fresh Term objects for a fit: built from strings and specs, copies of Term objects."""
        built: list[Term] = []
        for t in self.terms:
            if isinstance(t, str):
                t = parse_term(t, is_circular)
            built.append(
                build_term(t, is_circular) if isinstance(t, TermSpec) else copy.deepcopy(t)
            )
        if not built:
            raise WorkbenchError("a model needs at least one term")
        if all(t.is_mean for t in built):
            # the weights need at least one feature; a level is the natural one
            built.insert(0, ConstTerm())
        if self.max_basis is not None:
            for t in built:
                if isinstance(t, HilbertGPTerm) and t.dims >= 2:
                    t.max_basis = min(t.max_basis, max(self.max_basis, t.n_basis))
        return built

    # ---- layout of the parameter vector: [log noise] + feature-term log-hypers + mean-term thetas
    def _layout(self) -> None:
        self._feat_terms = [t for t in self.terms_ if not t.is_mean]
        self._mean_terms = [t for t in self.terms_ if t.is_mean]
        self.h_slices_, i = [], 1
        for t in self._feat_terms:
            k = len(t.hypers())
            self.h_slices_.append(slice(i, i + k))
            i += k
        self._m_slices = []
        for t in self._mean_terms:
            k = len(t.theta_init())
            self._m_slices.append(slice(i, i + k))
            i += k
        self._n_params = i

    def _bounds(self) -> list[tuple[float, float]]:
        b = [NOISE_BOUNDS]
        for t in self._feat_terms:
            b += [(h.lo, h.hi) for h in t.hypers()]
        for t in self._mean_terms:
            b += t.theta_bounds()
        return b

    def _clip(self, theta: np.ndarray) -> np.ndarray:
        bounds = self._bounds()
        return np.clip(theta, [b[0] for b in bounds], [b[1] for b in bounds])

    def _init(self, y: np.ndarray) -> np.ndarray:
        theta = [math.log(0.1)]
        for t in self._feat_terms:
            hs = t.hypers()
            vals = [h.init for h in hs]
            if t.describe() == "const":
                vals[0] = math.log((np.mean(y) / self.y_scale_) ** 2 + 1.0)
            theta += vals
        for t in self._mean_terms:
            theta += list(t.theta_init())
        return np.array(theta, float)

    def _loglam(self, theta: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        logs, ders = [], []
        for t, sl in zip(self._feat_terms, self.h_slices_, strict=True):
            lv, d = t.log_prior_var(theta[sl])
            logs.append(lv)
            ders.append(d)
        return np.concatenate(logs), ders

    def _mean(self, Zs: list[np.ndarray], theta: np.ndarray) -> np.ndarray:
        out = np.zeros(len(Zs[0]) if Zs else 0)
        for t, sl, Z in zip(self._mean_terms, self._m_slices, Zs, strict=True):
            out = out + t.mean(Z, theta[sl])
        return out

    def _objective(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        """Negative log marginal likelihood of the hyperparameter rows, and its gradient."""
        loglam, ders = self._loglam(theta)
        hd = self._hdesign
        if self._mean_terms:
            r = (self._hy - self._mean(self._hZmean, theta)) / self.y_scale_
            b, rr = hd.rmatvec(r), float(r @ r)
        else:
            r, b, rr = None, self._hb, self._hrr
        try:
            logp, g_lam, g_sn2, post = evidence(hd.G, b, rr, hd.n, loglam, theta[0])
        except (np.linalg.LinAlgError, ValueError):
            return 1e25, np.zeros_like(theta)
        grad = np.zeros_like(theta)
        grad[0] = g_sn2
        i = 0
        for sl, d in zip(self.h_slices_, ders, strict=True):
            m = d.shape[0]
            grad[sl] = g_lam[i : i + m] @ d
            i += m
        if self._mean_terms:
            self._mean_gradient(theta, r, hd.matvec(post["mu"]), post["sn2"], grad)
        if not np.isfinite(logp) or not np.all(np.isfinite(grad)):
            return 1e25, np.zeros_like(theta)
        return -logp, -grad

    def _mean_gradient(self, theta, r, fitted, sn2, grad) -> None:
        """The log evidence's gradient by the mean terms' parameters (into `grad`): the mean function's
        derivative by forward finite differences, times the posterior residual."""
        sinv_r = (r - fitted) / sn2
        for t, sl, Z in zip(self._mean_terms, self._m_slices, self._hZmean, strict=True):
            th = theta[sl]
            base = t.mean(Z, th)
            for k in range(len(th)):
                step = 1e-6 * max(1.0, abs(th[k]))
                th2 = th.copy()
                th2[k] += step
                dm = (t.mean(Z, th2) - base) / step / self.y_scale_
                grad[sl.start + k] = sinv_r @ dm

    def _prepare(self, X: Mapping[str, np.ndarray], y: np.ndarray, design: Design | None) -> None:
        y = np.asarray(y, float)
        if not np.all(np.isfinite(y)):
            raise WorkbenchError("the target has missing or non-finite values")
        self.y_scale_ = float(np.std(y)) or 1.0
        self._y = y
        if design is None:
            blocks = []
            for t in self.terms_:
                Z = term_inputs(t, X)
                t.setup(Z)
                if not t.is_mean:
                    blocks.append(t.features(Z))
            design = Design(blocks)
        self._layout()
        self._Zmean = [term_inputs(t, X) for t in self._mean_terms]
        self.design_ = design
        r = y / self.y_scale_
        self._b, self._rr = design.rmatvec(r), float(r @ r)
        rows = self.hyper_rows
        if rows is None or len(rows) >= len(y):
            self._hdesign, self._hb, self._hrr = design, self._b, self._rr
            self._hy, self._hZmean = y, self._Zmean
        else:
            self._hdesign = Design([b[rows] for b in design.blocks])
            self._hy, self._hZmean = y[rows], [Z[rows] for Z in self._Zmean]
            self._hb, self._hrr = self._hdesign.rmatvec(r[rows]), float(r[rows] @ r[rows])

    def _search_lengthscale(self, theta: np.ndarray) -> np.ndarray:
        """Start L-BFGS from the best of a few lengthscales for the first GP term (avoids poor local optima)."""
        for t, sl in zip(self._feat_terms, self.h_slices_, strict=True):
            if isinstance(t, HilbertGPTerm):
                lo, hi = math.log(t.l_min * 1.1), math.log(2.0 * float(t.half.max()))
                best, best_val = theta, self._objective(theta)[0]
                for logl in np.linspace(lo, hi, 7):
                    trial = theta.copy()
                    trial[sl.start + 1] = logl
                    val = self._objective(trial)[0]
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

    def fit(
        self,
        X: Mapping[str, np.ndarray],
        y: np.ndarray,
        init: np.ndarray | None = None,
        optimize: bool = True,
        design: Design | None = None,
    ) -> Model:
        """Fit hyperparameters by marginal likelihood (from `init` if given; kept as given if not `optimize`)
        and the posterior over weights. With `design`, the terms must already be set up for it (`extended`)."""
        self.terms_ = self._build_terms()
        self._prepare(X, y, design)
        theta = self._init(y) if init is None else np.asarray(init, float).copy()
        if len(theta) != self._n_params:
            raise WorkbenchError("initial hyperparameters do not match the model's terms")
        theta = self._clip(theta)
        if optimize:
            theta = self._optimize(theta, search=init is None)
            if design is None:
                theta = self._grow_basis(X, y, theta)
        self._set_posterior(theta)
        return self

    def _grow_basis(
        self, X: Mapping[str, np.ndarray], y: np.ndarray, theta: np.ndarray
    ) -> np.ndarray:
        """The basis resolves lengthscales down to l_min: while the optimum sits there, double the highest
        frequency (2^D times the functions) and resume the fit."""
        for _ in range(3):
            grow = [
                t
                for t, sl in zip(self._feat_terms, self.h_slices_, strict=True)
                if isinstance(t, HilbertGPTerm)
                and theta[sl.start + 1] < math.log(1.25 * t.l_min)
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

    def _set_posterior(self, theta: np.ndarray) -> None:
        with small_blas():
            self._set_posterior_inner(theta)

    def _set_posterior_inner(self, theta: np.ndarray) -> None:
        self.theta_ = theta
        loglam, _ = self._loglam(theta)
        if self._mean_terms:
            r = (self._y - self._mean(self._Zmean, theta)) / self.y_scale_
            self._r = r
            self._b, self._rr = self.design_.rmatvec(r), float(r @ r)
        else:
            self._r = self._y / self.y_scale_
        logp, _, _, post = evidence(
            self.design_.G, self._b, self._rr, self.design_.n, loglam, theta[0], grad=False
        )
        self.log_marginal_likelihood_ = float(logp)
        self._post = post
        self._loglam_ = loglam

    def _check_fitted(self) -> None:
        if not hasattr(self, "theta_"):
            raise NotFittedError("this Model is not fitted yet: call fit(X, y) first")

    @property
    def noise_std_(self) -> float:
        self._check_fitted()
        return math.sqrt(math.exp(self.theta_[0])) * self.y_scale_

    @property
    def params_(self) -> dict[str, dict[str, float]]:
        """Fitted parameters of every term, plus the noise standard deviation, in the target's units."""
        out: dict[str, dict[str, float]] = {"noise": {"std": self.noise_std_}}
        i = 0
        for t, sl, m in zip(self._feat_terms, self.h_slices_, self.design_.sizes, strict=True):
            w = self._post["mu"][i : i + m] * self.y_scale_
            p = t.params(self.theta_[sl], w)
            if "variance" in p:
                p["std"] = math.sqrt(p.pop("variance")) * self.y_scale_
            out[t.describe()] = p
            i += m
        for t, sl in zip(self._mean_terms, self._m_slices, strict=True):
            out[t.describe()] = t.params(self.theta_[sl], np.zeros(0))
        return out

    @property
    def n_basis_(self) -> dict[str, int]:
        """Basis functions of every reduced-rank GP term, as the fit left them (it may have grown them)."""
        self._check_fitted()
        return {t.describe(): t.n_basis for t in self.terms_ if isinstance(t, HilbertGPTerm)}

    def features(self, X: Mapping[str, np.ndarray]) -> list[np.ndarray]:
        self._check_fitted()
        return [t.features(term_inputs(t, X)) for t in self._feat_terms]

    def _predict_rows(self, Phi: np.ndarray, mean_part: np.ndarray, post: dict, return_std: bool):
        mu = Phi @ post["mu"] * self.y_scale_ + mean_part
        if not return_std:
            return mu, None
        V = linalg.solve_triangular(post["L"], (Phi * post["s"]).T, lower=True, check_finite=False)
        var = (V**2).sum(axis=0) * self.y_scale_**2
        return mu, np.sqrt(np.maximum(var, 0.0))

    def predict(
        self, X: Mapping[str, np.ndarray], return_std: bool = False, include_noise: bool = False
    ):
        """Posterior mean (and standard deviation of the latent field, or of a new observation)."""
        self._check_fitted()
        with small_blas():
            return self._predict(X, return_std, include_noise)

    def _predict(self, X, return_std, include_noise):
        n = len(next(iter(X.values())))
        means, stds = np.empty(n), np.empty(n)
        for a in range(0, n, CHUNK):
            Xc = {k: np.asarray(v)[a : a + CHUNK] for k, v in X.items()}
            mean_part = (
                self._mean([term_inputs(t, Xc) for t in self._mean_terms], self.theta_)
                if self._mean_terms
                else 0.0
            )
            Phi = np.hstack(self.features(Xc))
            mu, sd = self._predict_rows(Phi, mean_part, self._post, return_std)
            means[a : a + CHUNK] = mu
            if return_std:
                stds[a : a + CHUNK] = sd
        if not return_std:
            return means
        if include_noise:
            stds = np.sqrt(stds**2 + self.noise_std_**2)
        return means, stds

    def cv_predict(
        self, folds: np.ndarray, return_std: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Held-out mean and latent std (add `noise_std_` for a new observation) for every sample, refitting the
        weights per fold with the hyperparameters fixed: each fold costs O(M^3) via Gram downdates, not a new
        pass over the data. Without `return_std` the std is None: the triangular solves for it cost as much
        as the rest of the fold."""
        self._check_fitted()
        grams = self.design_.fold_grams(folds)
        sn2 = math.exp(self.theta_[0])
        loglam = self._loglam_
        mean_part = self._y - self._r * self.y_scale_
        mu_out = np.empty(self.design_.n)
        sd_out = np.empty(self.design_.n) if return_std else None
        with small_blas():
            self._cv_loop(folds, grams, loglam, sn2, mean_part, mu_out, sd_out)
        return mu_out, sd_out

    def _cv_loop(self, folds, grams, loglam, sn2, mean_part, mu_out, sd_out) -> None:
        for f, Gf in zip(np.unique(folds), grams, strict=True):
            test = folds == f
            Phi = self.design_.rows(test)
            b_tr = self._b - Phi.T @ self._r[test]
            G_tr = self.design_.G - Gf
            rr = float(self._r[~test] @ self._r[~test])
            _, _, _, post = evidence(
                G_tr, b_tr, rr, int((~test).sum()), loglam, self.theta_[0], grad=False
            )
            mu, sd = self._predict_rows(Phi, mean_part[test], post, sd_out is not None)
            mu_out[test] = mu
            if sd_out is not None:
                sd_out[test] = sd

    def extended(self, term: Term, X: Mapping[str, np.ndarray], y: np.ndarray) -> Model:
        """A new, fitted model with one more feature term, sharing this model's design (only cross products
        are new); every hyperparameter is refitted, starting from this model's values. Neither this model's
        terms nor `term` are changed or shared: the new model works on copies."""
        self._check_fitted()
        if term.is_mean:
            raise WorkbenchError("extended() takes a feature term")
        term = copy.deepcopy(term)
        Z = term_inputs(term, X)
        term.setup(Z)
        new = Model(
            copy.deepcopy(self._feat_terms + [term] + self._mean_terms),
            max_iter=self.max_iter,
            max_basis=self.max_basis,
            hyper_rows=self.hyper_rows,
        )
        design = self.design_.augment(term.features(Z))
        cut = self.h_slices_[-1].stop
        init = np.concatenate(
            [self.theta_[:cut], [h.init for h in term.hypers()], self.theta_[cut:]]
        )
        return new.fit(X, y, init=init, design=design)
