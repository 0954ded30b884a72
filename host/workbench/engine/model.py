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
from forcemap.host.workbench.engine import fourier
from forcemap.host.workbench.engine.evidence import (
    Design,
    DesignCache,
    SufficientStats,
    blas_threads,
    chunks,
    evidence,
    folds_key,
    small_blas,
)
from forcemap.host.workbench.engine.hypersearch import (
    FTOL,
    HYPER_SPACING_S,
    MIN_HYPER_ROWS,
    NOISE_BOUNDS,
    HyperSearch,
    basis_stats,
    fixed_basis,
    spaced_rows,
    term_inputs,
)
from forcemap.host.workbench.engine.model_setup import build_design, build_terms
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.base import Term, TermSpec
from forcemap.host.workbench.terms.spec import BASELINE
from scipy import linalg

CHUNK = 8192
# where callers have always found them
__all__ = [
    "FTOL",
    "HYPER_SPACING_S",
    "MIN_HYPER_ROWS",
    "NOISE_BOUNDS",
    "Design",
    "DesignCache",
    "Model",
    "NotFittedError",
    "SufficientStats",
    "basis_stats",
    "fixed_basis",
    "blas_threads",
    "evidence",
    "small_blas",
    "spaced_rows",
    "term_inputs",
]


class NotFittedError(ValueError, AttributeError):
    """The model is used before `fit` (the same bases as scikit-learn's NotFittedError)."""


class Model(HyperSearch):
    """A sum of terms. Feature terms (GPs, linear, cosine) are Bayesian linear regression in fixed features;
    mean terms (power law, user functions) are subtracted with parameters fitted by marginal likelihood.

    `terms`: term strings, `TermSpec`s or `Term` objects (copied by `fit`, never changed). `max_basis` caps the
    basis of a spatial GP term. With `hyper_spacing_s`, the hyperparameters are set by the marginal likelihood
    of the samples that far apart in the input "t" (`spaced_rows`); the posterior always uses every row.
    `init` starts the hyperparameter search (the layout of `theta_`); without `optimize` they are kept as given.
    `memory` (a `DesignCache`) shares Gram matrices between models with the same features on the same inputs."""

    def __init__(
        self,
        terms: Sequence[Term | TermSpec | str] = tuple(BASELINE),
        max_iter: int = 300,
        max_basis: int | None = None,
        hyper_spacing_s: float | None = None,
        init: np.ndarray | None = None,
        optimize: bool = True,
        memory: DesignCache | None = None,
    ) -> None:
        self.terms = terms
        self.max_iter = max_iter
        self.max_basis = max_basis
        self.hyper_spacing_s = hyper_spacing_s
        self.init = init
        self.optimize = optimize
        self.memory = memory

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
        return build_terms(self.terms, self.max_basis)

    def _prepare(self, X: Mapping[str, np.ndarray], y: np.ndarray, design: Design | None) -> None:
        """Scale the target, set the terms up (unless `design` is given: then they are), and gather what the
        hyperparameter search needs: the design of the hyperparameter rows holds its features, the design
        of every row computes its Gram matrix only when the posterior needs it."""
        y = np.asarray(y, float)
        if not np.all(np.isfinite(y)):
            raise WorkbenchError("the target has missing or non-finite values")
        self.y_scale_ = float(np.std(y)) or 1.0
        self.target_ = y
        inputs = [term_inputs(t, X) for t in self.terms_]
        if design is None:
            for t, Z in zip(self.terms_, inputs, strict=True):
                t.setup(Z)
        self._layout()
        self._Zmean = [Z for t, Z in zip(self.terms_, inputs, strict=True) if t.is_mean]
        if design is None:
            feat = [(t, Z) for t, Z in zip(self.terms_, inputs, strict=True) if not t.is_mean]
            design = build_design(feat, self.memory)
        self.design_ = design
        r = y / self.y_scale_
        rows = self._hyper_rows(X, len(y))
        if rows is None:
            self._hdesign, self._hy, self._hZmean = design, y, self._Zmean
        else:
            self._hdesign = design.subset(rows)
            self._hy, self._hZmean = y[rows], [Z[rows] for Z in self._Zmean]
        hr = r if rows is None else r[rows]
        self._hb, self._hrr = self._hdesign.rmatvec(hr), float(hr @ hr)

    def _hyper_rows(self, X: Mapping[str, np.ndarray], n: int) -> np.ndarray | None:
        if self.hyper_spacing_s is None:
            return None
        if "t" not in X:
            raise WorkbenchError("hyper_spacing_s needs the input 't' (the samples' times)")
        return spaced_rows(X["t"], self.hyper_spacing_s)

    def fit(self, X: Mapping[str, np.ndarray], y: np.ndarray) -> Model:
        """Fit the hyperparameters by marginal likelihood (from `init` if given; kept as given without
        `optimize`) and the posterior over the weights."""
        self.terms_ = self._build_terms()
        return self._fit(X, y, None)

    def fit_design(self, X: Mapping[str, np.ndarray], y: np.ndarray, design: Design) -> Model:
        """`fit` on a design already built for these terms (`Design.augment` of another model's): the terms
        must be set up for it, and their bases are not grown."""
        self.terms_ = self._build_terms()
        return self._fit(X, y, design)

    def _fit(self, X: Mapping[str, np.ndarray], y: np.ndarray, design: Design | None) -> Model:
        self._prepare(X, y, design)
        init = self.init
        theta = self._init(y) if init is None else np.asarray(init, float).copy()
        if len(theta) != self._n_params:
            raise WorkbenchError("initial hyperparameters do not match the model's terms")
        theta = self._clip(theta)
        if self.optimize:
            theta = self._optimize(theta, search=init is None)
            if design is None:
                theta = self._grow_basis(X, y, theta)
        self._set_posterior(theta)
        # the search's scratch: the hyperparameter rows' design and inputs
        del self._hdesign, self._hy, self._hZmean, self._hb, self._hrr
        return self

    def _set_posterior(self, theta: np.ndarray) -> None:
        with small_blas():
            self._set_posterior_inner(theta)

    def _set_posterior_inner(self, theta: np.ndarray) -> None:
        self.theta_ = theta
        loglam, _ = self._loglam(theta)
        r = self.target_ / self.y_scale_
        if self.mean_terms_:
            r = (self.target_ - self._mean(self._Zmean, theta)) / self.y_scale_
        self.scaled_residual_ = r
        G, b, fold_b = self.design_.products(r)
        self.feature_residual_ = b
        # Phi_f'r_f per fold of the design's planned assignment, from the same pass (for `cv_predict`)
        plan = self.design_.plan
        self.fold_residuals_ = {} if fold_b is None else {folds_key(plan): fold_b}
        logp, _, _, post = evidence(
            G, b, float(r @ r), self.design_.n, loglam, theta[0], grad=False
        )
        self.log_marginal_likelihood_ = float(logp)
        self.posterior_ = post
        self.loglam_ = loglam

    def _check_fitted(self) -> None:
        if not hasattr(self, "theta_"):
            raise NotFittedError("this Model is not fitted yet: call fit(X, y) first")

    @property
    def noise_std_(self) -> float:
        self._check_fitted()
        return math.sqrt(math.exp(self.theta_[0])) * self.y_scale_

    @property
    def position_lengthscale_(self) -> float | None:
        """The fitted lengthscale (m) of the first GP term over position, or None when it has none."""
        for t, sl in zip(self.feat_terms_, self.h_slices_, strict=True):
            if t.grows_basis and t.inputs[:1] == ("position",):
                return float(math.exp(self.theta_[sl][t.hyper_index("lengthscale")]))
        return None

    @property
    def params_(self) -> dict[str, dict[str, float]]:
        """Fitted parameters of every term, plus the noise standard deviation, in the target's units."""
        out: dict[str, dict[str, float]] = {"noise": {"std": self.noise_std_}}
        i = 0
        for t, sl, m in zip(self.feat_terms_, self.h_slices_, self.design_.sizes, strict=True):
            w = self.posterior_["mu"][i : i + m] * self.y_scale_
            p = t.params(self.theta_[sl], w)
            if "variance" in p:
                p["std"] = math.sqrt(p.pop("variance")) * self.y_scale_
            out[t.describe()] = p
            i += m
        for t, sl in zip(self.mean_terms_, self.m_slices_, strict=True):
            out[t.describe()] = t.params(self.theta_[sl], np.zeros(0))
        return out

    @property
    def n_basis_(self) -> dict[str, int]:
        """Basis functions of every reduced-rank GP term, as the fit left them (it may have grown them)."""
        self._check_fitted()
        return {t.describe(): t.n_basis for t in self.terms_ if t.grows_basis}

    def features(self, X: Mapping[str, np.ndarray]) -> list[np.ndarray]:
        self._check_fitted()
        return [t.features(term_inputs(t, X)) for t in self.feat_terms_]

    def _predict_rows(self, Phi, Zf, mean_part, post: dict, return_std: bool):
        """Mean and latent std at rows with features `Phi` (and the fast GP term's inputs `Zf`)."""
        mu = Phi @ post["mu"] * self.y_scale_ + mean_part
        if not return_std:
            return mu, None
        fast = self.design_.fast
        if fast is None:
            V = linalg.solve_triangular(
                post["L"], (Phi * post["s"]).T, lower=True, check_finite=False
            )
            var = (V**2).sum(axis=0)
        else:
            fcols, slow = cols = self.design_.fast_cols
            fourier.posterior_tables(fast[1], cols, post)
            cross = Phi[:, fcols] @ post["cov_slow"][:, fcols].T
            var = fourier.variance(fast[1], Zf, cols, post, Phi[:, slow], cross)
        return mu, np.sqrt(np.maximum(var * self.y_scale_**2, 0.0))

    def _predict_fast_rows(self, Xc, mean_part, post: dict, return_std: bool):
        """`_predict_rows` where the design has a fast GP block, from inputs: the block's features are never
        formed, its linear forms (the mean, the slow columns' covariances with it) come from sine tables."""
        i, term = self.design_.fast[:2]
        feats = [t.features(term_inputs(t, Xc)) for k, t in enumerate(self.feat_terms_) if k != i]
        Zf = term_inputs(term, Xc)
        S = np.hstack(feats) if feats else np.empty((len(Zf), 0))
        return self._predict_fast(S, Zf, mean_part, post, return_std)

    def _predict_fast(self, S, Zf, mean_part, post: dict, return_std: bool, cosines=None):
        """`_predict_fast_rows` from the other blocks' features `S` and the fast block's inputs `Zf`. The
        sines come from a table of twice the phases when the cosines are made too (`cosines`, by default
        `return_std`): the means agree with those from the sines alone to an ulp, not to the bit."""
        term = self.design_.fast[1]
        fcols, slow = cols = self.design_.fast_cols
        if "mean_table" not in post:
            post["mean_table"] = fourier.linear_table(term, post["mu"][fcols])
        waves = fourier.waves(term, Zf, cosines=return_std if cosines is None else cosines)
        mu = fourier.linear_form(term, Zf, post["mean_table"], waves)[:, 0] + S @ post["mu"][slow]
        mu = mu * self.y_scale_ + mean_part
        if not return_std:
            return mu, None
        fourier.posterior_tables(term, cols, post)
        cross = fourier.linear_form(term, Zf, post["cross_table"], waves) if len(slow) else None
        var = fourier.variance(term, Zf, cols, post, S, cross, waves)
        return mu, np.sqrt(np.maximum(var * self.y_scale_**2, 0.0))

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
                self._mean([term_inputs(t, Xc) for t in self.mean_terms_], self.theta_)
                if self.mean_terms_
                else 0.0
            )
            if self.design_.fast is not None:
                mu, sd = self._predict_fast_rows(Xc, mean_part, self.posterior_, return_std)
            else:
                Phi = np.hstack(self.features(Xc))
                mu, sd = self._predict_rows(Phi, None, mean_part, self.posterior_, return_std)
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
        loglam = self.loglam_
        mean_part = self.target_ - self.scaled_residual_ * self.y_scale_
        mu_out = np.empty(self.design_.n)
        sd_out = np.empty(self.design_.n) if return_std else None
        with small_blas():
            self._cv_loop(folds, grams, loglam, sn2, mean_part, mu_out, sd_out)
        return mu_out, sd_out

    def _cv_loop(self, folds, grams, loglam, sn2, mean_part, mu_out, sd_out) -> None:
        design, r = self.design_, self.scaled_residual_
        fold_b = self.fold_residuals_.get(folds_key(folds))
        for i, (f, Gf) in enumerate(zip(np.unique(folds), grams, strict=True)):
            test = folds == f
            bf = fold_b[i] if fold_b is not None else design.rmatvec(r, test)
            rr = float(r[~test] @ r[~test])
            _, _, _, post = evidence(
                design.G - Gf,
                self.feature_residual_ - bf,
                rr,
                int((~test).sum()),
                loglam,
                self.theta_[0],
                grad=False,
            )
            for idx, mu, sd in self._fold_predictions(test, mean_part, post, sd_out is not None):
                mu_out[idx] = mu
                if sd_out is not None:
                    sd_out[idx] = sd

    def _fold_predictions(self, test, mean_part, post: dict, return_std: bool):
        """(rows, mean, std) of a fold's held-out rows in chunks; a fast GP block's without its features."""
        design = self.design_
        if design.fast is None:
            for idx, Phi in design.row_chunks(test):
                yield idx, *self._predict_rows(Phi, None, mean_part[idx], post, return_std)
            return
        i, _, Zf = design.fast
        for idx in chunks(np.flatnonzero(test), CHUNK):
            S = [b[idx] for k, b in enumerate(design.blocks) if k != i]
            S = np.hstack(S) if S else np.empty((len(idx), 0))
            # the same tables with or without the spread: the held-out means do not depend on asking for it
            yield idx, *self._predict_fast(S, Zf[idx], mean_part[idx], post, return_std, True)

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
        design = self.design_.augment(term.features(Z))
        cut = self.h_slices_[-1].stop
        init = np.concatenate(
            [self.theta_[:cut], [h.init for h in term.hypers()], self.theta_[cut:]]
        )
        new = Model(
            copy.deepcopy(self.feat_terms_ + [term] + self.mean_terms_),
            max_iter=self.max_iter,
            max_basis=self.max_basis,
            hyper_spacing_s=self.hyper_spacing_s,
            init=init,
            memory=self.memory,
        )
        return new.fit_design(X, y, design)
