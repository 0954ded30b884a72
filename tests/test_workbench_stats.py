"""Sufficient statistics and the cosine-table shortcuts: a reduced-rank GP's Gram matrix and predictive
variance from `fourier` equal the direct products; statistics of chunks of rows add up to those of all the
rows; a fit from summed statistics is the fit of the rows; a design that computes its features chunk by
chunk fits and cross-validates exactly as one that holds them."""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.workbench.engine import evidence, fourier, nufft
from forcemap.host.workbench.engine.model import Model, basis_stats, fixed_basis
from forcemap.host.workbench.terms.gp import HilbertGPTerm


@pytest.fixture(scope="module")
def field():
    rng = np.random.default_rng(3)
    n = 2500
    xy = rng.uniform([-300, -60], [300, 60], (n, 2)) @ np.array([[0.9, 0.3], [-0.3, 0.9]])
    y = 1.0 + np.sin(xy[:, 0] / 45.0) * np.cos(xy[:, 1] / 30.0) + 0.05 * rng.standard_normal(n)
    return xy, y, np.arange(n) * 0.25


@pytest.mark.parametrize("dims, n_basis", [(2, 300), (1, 80)])
def test_cosine_tables_equal_the_direct_products(field, dims, n_basis):
    xy, _, t = field
    Z = xy if dims == 2 else t[:, None]
    term = HilbertGPTerm(("position",) if dims == 2 else ("t",), "matern32", n_basis, dims)
    term.setup(Z)
    F = term.features(Z)
    G = F.T @ F
    np.testing.assert_allclose(fourier.gram(term, Z), G, rtol=0, atol=1e-11 * np.abs(G).max())
    rng = np.random.default_rng(0)
    A = rng.standard_normal((n_basis, n_basis))
    C = A @ A.T / n_basis
    direct = np.einsum("ij,ij->i", F @ C, F)
    table = fourier.quadratic_form(term, Z, fourier.variance_table(term, C))
    np.testing.assert_allclose(table, direct, rtol=1e-10, atol=1e-12 * direct.max())
    # the linear forms (a mean, covariances) from sine tables, and the cosines of `waves` as the Gram's
    W = rng.standard_normal((n_basis, 3))
    lin = fourier.linear_form(term, Z, fourier.linear_table(term, W), fourier.waves(term, Z))
    np.testing.assert_allclose(lin, F @ W, rtol=0, atol=1e-12 * np.abs(F @ W).max())
    with nufft.direct():  # the tables themselves, as without finufft
        waves = fourier.waves(term, Z)
        lin = fourier.linear_form(term, Z, fourier.linear_table(term, W), waves)
        np.testing.assert_allclose(lin, F @ W, rtol=0, atol=1e-12 * np.abs(F @ W).max())
        table = fourier.quadratic_form(term, Z, fourier.variance_table(term, C), waves)
        np.testing.assert_allclose(table, direct, rtol=1e-10, atol=1e-12 * direct.max())
    for got, want in zip(waves[0], fourier._cosines(term, Z), strict=True):
        assert got.shape == want.shape and np.abs(got - want).max() < 1e-13


@pytest.mark.parametrize("dims, n_basis", [(2, 300), (1, 80)])
def test_sine_table_products_equal_the_direct_products(field, dims, n_basis):
    xy, y, t = field
    Z = xy if dims == 2 else t[:, None]
    term = HilbertGPTerm(("position",) if dims == 2 else ("t",), "matern32", n_basis, dims)
    term.setup(Z)
    W = np.column_stack([np.ones(len(y)), y, np.cos(t)])
    direct = term.features(Z).T @ W
    got = fourier.transpose_products(term, Z, W, rows=700)  # several row chunks
    np.testing.assert_allclose(got, direct, rtol=0, atol=1e-12 * np.abs(direct).max())


def test_design_pass_without_the_gp_features_equals_the_dense_pass(field):
    """A design with a fast GP block takes its Gram matrix from cosine tables and its products with the other
    blocks and with the residual from sine tables; the results are the products of the features."""
    xy, y, t = field
    gp = HilbertGPTerm(("position",), "matern32", 300, 2)
    gp.setup(xy)
    slow = np.column_stack([np.ones(len(y)), (t - t.mean()) / t.std()])
    blocks = [slow[:, :1], evidence.TermBlock(gp, xy), slow[:, 1:]]
    folds = np.arange(len(y)) % 3
    fast = evidence.Design(blocks, plan=folds, fast=(1, gp, xy))
    Phi = np.hstack([slow[:, :1], gp.features(xy), slow[:, 1:]])
    G, b, fold_b = fast.products(y)
    scale = np.abs(Phi.T @ Phi).max()
    np.testing.assert_allclose(G, Phi.T @ Phi, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(b, Phi.T @ y, rtol=0, atol=1e-12 * np.abs(Phi.T @ y).max())
    for f, (Gf, bf) in enumerate(zip(fast.fold_grams(folds), fold_b, strict=True)):
        rows = folds == f
        np.testing.assert_allclose(Gf, Phi[rows].T @ Phi[rows], rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(bf, Phi[rows].T @ y[rows], rtol=0, atol=1e-12 * scale)


def test_chunk_statistics_add_up_to_the_whole(field):
    xy, y, _ = field
    X = {"position": xy}
    terms = fixed_basis(["const", "gp(position, matern32)"], X)
    whole = basis_stats(terms, X, y)
    parts = [
        basis_stats(terms, {"position": xy[a : a + 700]}, y[a : a + 700])
        for a in range(0, len(y), 700)
    ]
    total = sum(parts[1:], parts[0])
    Phi = np.hstack([t.features(xy if t.inputs else np.zeros((len(y), 0))) for t in terms])
    for got in (whole, total):
        np.testing.assert_allclose(got.G, Phi.T @ Phi, rtol=1e-10, atol=1e-10 * len(y))
        np.testing.assert_allclose(got.b, Phi.T @ y, rtol=1e-10, atol=1e-10 * len(y))
        assert got.n == len(y) and got.yy == pytest.approx(y @ y, rel=1e-12)
        assert got.ysum == pytest.approx(y.sum(), rel=1e-12)


def test_fit_from_summed_statistics_is_the_fit_of_the_rows(field):
    xy, y, _ = field
    X = {"position": xy}
    terms = fixed_basis(["const", "gp(position, matern32)"], X)
    parts = [
        basis_stats(terms, {"position": xy[a : a + 900]}, y[a : a + 900])
        for a in range(0, len(y), 900)
    ]
    from_stats = Model(terms).fit_stats(sum(parts[1:], parts[0]))
    # max_basis=1: the basis stays as set up, as fit_stats keeps it
    from_rows = Model(terms, max_basis=1).fit(X, y)
    np.testing.assert_allclose(from_stats.theta_, from_rows.theta_, rtol=1e-5, atol=1e-5)
    grid = {"position": xy[::50]}
    mu_s, sd_s = from_stats.predict(grid, return_std=True)
    mu_r, sd_r = from_rows.predict(grid, return_std=True)
    np.testing.assert_allclose(mu_s, mu_r, rtol=0, atol=1e-5)
    np.testing.assert_allclose(sd_s, sd_r, rtol=1e-4)
    assert set(from_stats.params_) == set(from_rows.params_)


def test_features_chunk_by_chunk_fit_as_held_features(field, monkeypatch):
    xy, y, t = field
    X = {"position": xy, "t": t}
    folds = (xy[:, 0] // 120).astype(int) % 5
    held = Model(["const", "gp(position, matern32)"], hyper_spacing_s=2.0).fit(X, y)
    # neither the fit nor the CV forms the GP block's features (cosine and sine tables)
    held_cv = held.cv_predict(folds)
    held_map = held.predict(X, return_std=True)
    monkeypatch.setattr(evidence, "DENSE_BYTES", 0)
    monkeypatch.setattr(evidence, "CHUNK_ROWS", 300)
    chunked = Model(["const", "gp(position, matern32)"], hyper_spacing_s=2.0).fit(X, y)
    np.testing.assert_allclose(chunked.theta_, held.theta_, rtol=1e-8, atol=1e-8)
    for a, b in zip(chunked.cv_predict(folds), held_cv, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-10)
    assert chunked.design_.lazy and held.design_.lazy
    np.testing.assert_allclose(chunked.predict(X, return_std=True), held_map, rtol=1e-8, atol=1e-10)
