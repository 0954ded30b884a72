"""The estimator: reduced-rank GP against an exact GP, gradients, parametric and user terms, fold refits."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from forcemap.host.workbench.engine.model import Model, evidence
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.terms.gp import HilbertGPTerm


def matern32(a, b, ell, var):
    r = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1))
    s = math.sqrt(3) * r / ell
    return var * (1 + s) * np.exp(-s)


@pytest.fixture(scope="module")
def field():
    rng = np.random.default_rng(3)
    n = 600
    xy = rng.uniform([-200, -60], [200, 60], size=(n, 2))
    f = 1.2 + 0.6 * np.sin(xy[:, 0] / 60.0) * np.cos(xy[:, 1] / 40.0)
    return xy, f, f + 0.1 * rng.standard_normal(n)


def test_reduced_rank_matches_exact_gp_with_same_hyperparameters(field):
    xy, f, y = field
    m = Model(["const", "gp(position, matern32)"]).fit({"position": xy}, y)
    p = m.params_
    ell, sd, noise = (
        p["gp(position, matern32)"]["lengthscale"],
        p["gp(position, matern32)"]["std"],
        p["noise"]["std"],
    )
    c = p["const"]["value"]
    K = matern32(xy, xy, ell, sd**2) + noise**2 * np.eye(len(y))
    exact = c + matern32(xy, xy, ell, sd**2) @ np.linalg.solve(K, y - c)
    mu = m.predict({"position": xy})
    assert np.sqrt(np.mean((mu - exact) ** 2)) < 0.15 * noise
    assert np.sqrt(np.mean((mu - f) ** 2)) < 0.5 * noise
    assert 0.07 < noise < 0.13


def test_evidence_gradient_matches_finite_differences():
    rng = np.random.default_rng(0)
    Phi = rng.standard_normal((200, 12))
    y = Phi @ rng.standard_normal(12) + 0.3 * rng.standard_normal(200)
    G, b, rr = Phi.T @ Phi, Phi.T @ y, float(y @ y)
    loglam, logsn2 = rng.normal(0, 0.5, 12), math.log(0.2)
    lp, g_lam, g_sn2, _ = evidence(G, b, rr, 200, loglam, logsn2)
    # against the dense Gaussian log density
    S = Phi @ np.diag(np.exp(loglam)) @ Phi.T + math.exp(logsn2) * np.eye(200)
    _, logdet = np.linalg.slogdet(S)
    dense = -0.5 * (y @ np.linalg.solve(S, y) + logdet + 200 * math.log(2 * math.pi))
    assert lp == pytest.approx(dense, rel=1e-9)
    eps = 1e-6
    for i in (0, 5, 11):
        d = loglam.copy()
        d[i] += eps
        num = (evidence(G, b, rr, 200, d, logsn2, grad=False)[0] - lp) / eps
        assert g_lam[i] == pytest.approx(num, rel=1e-3, abs=1e-5)
    num = (evidence(G, b, rr, 200, loglam, logsn2 + eps, grad=False)[0] - lp) / eps
    assert g_sn2 == pytest.approx(num, rel=1e-3, abs=1e-5)


@pytest.mark.parametrize("kernel", ["rbf", "matern12", "matern32", "matern52"])
def test_spectral_density_gradient(kernel):
    term = HilbertGPTerm(("position",), kernel, n_basis=50, dims=2)
    term.setup(np.random.default_rng(1).uniform(-100, 100, (50, 2)))
    h = np.array([0.3, math.log(40.0)])
    lv, d = term.log_prior_var(h)
    h2 = h.copy()
    h2[1] += 1e-6
    num = (term.log_prior_var(h2)[0] - lv) / 1e-6
    assert np.allclose(d[:, 1], num, rtol=1e-4, atol=1e-6)


def test_periodic_term_recovers_a_heading_effect():
    rng = np.random.default_rng(2)
    n = 800
    heading = rng.uniform(0, 360, n)
    y = 0.5 * np.sin(np.radians(heading + 40)) + 0.05 * rng.standard_normal(n)
    m = Model(["const", "gp(heading, periodic)"]).fit({"heading": heading}, y)
    grid = np.linspace(0, 359, 50)
    pred = m.predict({"heading": grid})
    assert np.max(np.abs(pred - 0.5 * np.sin(np.radians(grid + 40)))) < 0.08


def test_power_law_parameters_are_fitted():
    rng = np.random.default_rng(4)
    depth = rng.uniform(0.5, 6.0, 500)
    y = 0.9 * depth ** (2 / 3) + 0.02 * rng.standard_normal(500)
    m = Model(["power(depth)"]).fit({"depth": depth}, y)
    p = m.params_["power(depth)"]
    # a * (d / d_ref)^b  ==  0.9 d^(2/3)
    assert p["b"] == pytest.approx(2 / 3, abs=0.05)
    assert p["a"] * p["z_ref"] ** (-p["b"]) == pytest.approx(0.9, rel=0.05)


def test_user_term_loaded_by_module_function(tmp_path, monkeypatch):
    (tmp_path / "mylaws.py").write_text(
        "def manning(depth, k=1.0):\n    return k * depth ** (2.0 / 3.0)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    rng = np.random.default_rng(5)
    depth = rng.uniform(0.5, 6.0, 400)
    y = 0.7 * depth ** (2 / 3) + 0.02 * rng.standard_normal(400)
    m = Model(["user(depth, mylaws:manning)"]).fit({"depth": depth}, y)
    assert m.params_["user(depth, mylaws:manning)"]["k"] == pytest.approx(0.7, rel=0.03)
    sys.modules.pop("mylaws", None)


def test_unknown_user_function_is_a_clear_error():
    depth = np.linspace(1.0, 5.0, 50)
    with pytest.raises(WorkbenchError, match="cannot import"):
        Model(["user(depth, no_such_module_xyz:f)"]).fit({"depth": depth}, depth)


def test_fold_predictions_equal_a_refit_on_the_training_rows(field):
    xy, _, y = field
    m = Model(["const", "gp(position, matern32)"]).fit({"position": xy}, y)
    folds = np.arange(len(y)) % 4
    mu, sd = m.cv_predict(folds)
    test = folds == 2
    # same basis (domain fixed on all data) and hyperparameters
    refit = Model(m.terms_, init=m.theta_, optimize=False)
    refit.fit({"position": xy[~test]}, y[~test])
    # the refit re-ran setup() on the training rows only, so compare with a tolerance
    mu2 = refit.predict({"position": xy[test]})
    assert np.sqrt(np.mean((mu[test] - mu2) ** 2)) < 0.02
    assert np.all(sd > 0)


def test_extended_model_shares_design_and_improves_fit():
    rng = np.random.default_rng(6)
    n = 700
    xy = rng.uniform(-100, 100, (n, 2))
    z = rng.uniform(0, 10, n)
    y = np.sin(xy[:, 0] / 40) + 0.4 * np.sin(z) + 0.05 * rng.standard_normal(n)
    base = Model(["const", "gp(position, matern32)"]).fit({"position": xy}, y)
    from forcemap.host.workbench.survey.table import is_circular
    from forcemap.host.workbench.terms.registry import build_term, parse_term

    X = {"position": xy, "z": z}
    ext = base.extended(build_term(parse_term("z", is_circular), is_circular), X, y)
    assert ext.log_marginal_likelihood_ > base.log_marginal_likelihood_ + 50
    assert ext.noise_std_ < 0.6 * base.noise_std_


def test_augmented_fold_grams_equal_the_grams_of_the_augmented_rows(field):
    """Design.augment sums the new block's cross products over the cells of every cached fold assignment;
    each fold's Gram must still be the Gram of that fold's rows of the augmented design."""
    xy, _, y = field
    m = Model(["const", "gp(position, matern32)"]).fit({"position": xy}, y)
    rng = np.random.default_rng(8)
    blocked = [(xy[:, 0] // 80).astype(int) % 5, ((xy[:, 0] + 40) // 80).astype(int) % 5]
    shuffled = rng.permutation(np.arange(len(y)) % 5)
    for folds in [*blocked, shuffled]:
        m.design_.fold_grams(folds)
    new = np.column_stack([np.sin(xy[:, 1] / 17.0), xy[:, 0] / 100.0, np.ones(len(y))])
    aug = m.design_.augment(new)
    full = np.hstack([m.design_.rows(slice(None)), new])
    for folds in [*blocked, shuffled]:
        for f, G in zip(np.unique(folds), aug.fold_grams(folds), strict=True):
            rows = full[folds == f]
            np.testing.assert_allclose(G, rows.T @ rows, rtol=1e-10, atol=1e-9)


def test_held_out_means_do_not_depend_on_asking_for_the_spread(field):
    xy, _, y = field
    m = Model(["const", "gp(position, matern32)"]).fit({"position": xy}, y)
    folds = np.arange(len(y)) % 4
    mu, sd = m.cv_predict(folds)
    mu_only, none = m.cv_predict(folds, return_std=False)
    assert none is None and np.all(sd > 0)
    np.testing.assert_array_equal(mu, mu_only)
