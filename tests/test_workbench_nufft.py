"""The Gram matrices and cross products of a reduced-rank GP block by non-uniform FFT (finufft) equal the direct
sums: every table, a model's fit, its blocked CV and its map, with the same hyperparameters, to 1e-8 relative;
and the same numbers run after run (finufft on one thread)."""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.workbench.engine import fourier, nufft
from forcemap.host.workbench.engine.model import Model
from forcemap.host.workbench.terms.gp import HilbertGPTerm
from forcemap.host.workbench.validation.cv import blocked_folds


@pytest.fixture(scope="module")
def survey():
    """A lawnmower over a 600 m x 150 m reach, with a bed of sand bars and a depth-like covariate."""
    rng = np.random.default_rng(7)
    n = 4000
    s = np.linspace(0.0, 1.0, n)
    x = 280.0 * np.sin(2 * np.pi * 9 * s)
    y = -70.0 + 140.0 * s + 2.0 * rng.standard_normal(n)
    xy = np.column_stack([x, y]) @ np.array([[0.96, 0.28], [-0.28, 0.96]])
    z = 1.2 * np.sin(xy[:, 0] / 9.5) * np.cos(xy[:, 1] / 7.0) + 0.05 * rng.standard_normal(n)
    depth = 3.0 + 0.01 * xy[:, 0] + 0.2 * rng.standard_normal(n)
    return {"position": xy, "depth": depth, "t": np.arange(n) * 0.5}, z


def test_finufft_is_installed():
    # the test extra installs the [nufft] extra: without it every other test here compares the direct path
    # with itself
    assert nufft.available()


@pytest.mark.parametrize("dims, n_basis", [(2, 1200), (1, 100)])
def test_tables_by_nufft_equal_the_direct_sums(survey, dims, n_basis):
    X, z = survey
    Z = X["position"] if dims == 2 else X["t"][:, None]
    term = HilbertGPTerm(("position",) if dims == 2 else ("t",), "matern32", n_basis, dims)
    term.setup(Z)
    W = np.column_stack([np.ones(len(z)), z, X["depth"]])
    G, cross = fourier.gram(term, Z), fourier.transpose_products(term, Z, W)
    with nufft.direct():
        G0, cross0 = fourier.gram(term, Z), fourier.transpose_products(term, Z, W)
    assert np.abs(G - G0).max() <= 1e-13 * np.abs(G0).max()
    assert np.abs(cross - cross0).max() <= 1e-13 * np.abs(cross0).max()
    # against the features themselves
    F = term.features(Z)
    assert np.abs(G - F.T @ F).max() <= 1e-12 * np.abs(G0).max()


def _fit_cv_map(X, z, init=None):
    gp = HilbertGPTerm(("position",), "matern32", 800, 2)
    gp.max_basis = 800  # not grown: the same basis with and without the hyperparameter search
    terms = ["const", gp, "gp(depth, matern32)"]
    m = Model(terms, init=init, optimize=init is None).fit(X, z)
    folds = blocked_folds(X["position"], 5, seed=0)[0]
    m.design_.plan = None
    cv_mu, cv_sd = m.cv_predict(folds)
    lo, hi = X["position"].min(axis=0), X["position"].max(axis=0)
    g = np.stack(np.meshgrid(*[np.linspace(a, b, 40) for a, b in zip(lo, hi, strict=True)]), -1)
    grid = {"position": g.reshape(-1, 2), "depth": np.full(1600, 3.0)}
    mean, sd = m.predict(grid, return_std=True)
    return m, {"mu": m.posterior_["mu"], "cv": cv_mu, "cv_sd": cv_sd, "mean": mean, "sd": sd}


def test_a_model_by_nufft_equals_the_direct_one(survey):
    """Fit, blocked CV (fold Grams by downdates) and map with the same hyperparameters: to 1e-8 relative."""
    X, z = survey
    fitted, fast = _fit_cv_map(X, z)
    assert fourier.is_fast(fitted.design_.fast[1])  # the fast block is used
    fitted2, again = _fit_cv_map(X, z, init=fitted.theta_)
    with nufft.direct():
        _, dense = _fit_cv_map(X, z, init=fitted.theta_)
    for k, v in dense.items():
        scale = np.abs(v).max()
        assert np.abs(again[k] - v).max() <= 1e-8 * scale, k
        # one thread, the same order of sums: the same bits run after run
        _, third = _fit_cv_map(X, z, init=fitted.theta_) if k == "mu" else (None, again)
        assert np.array_equal(third[k], again[k])
    assert abs(fitted2.log_marginal_likelihood_ - fitted.log_marginal_likelihood_) <= 1e-8 * abs(
        fitted.log_marginal_likelihood_
    )
