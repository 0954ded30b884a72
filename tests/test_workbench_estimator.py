"""The estimator follows scikit-learn's conventions: scikit-learn's own checks that need no data, and its
data checks rewritten for named inputs (its `check_estimator` feeds 2-D arrays; `Model` takes a mapping)."""

from __future__ import annotations

import copy
import pickle

import joblib
import numpy as np
import pytest
from forcemap.host.workbench.engine.model import DesignCache, Model, NotFittedError, spaced_rows
from forcemap.host.workbench.survey.table import is_circular
from forcemap.host.workbench.terms.registry import build_term, parse_term
from sklearn.base import clone
from sklearn.model_selection import GroupKFold, KFold
from sklearn.utils import estimator_checks as ec

NO_DATA_CHECKS = [
    ec.check_no_attributes_set_in_init,
    ec.check_get_params_invariance,
    ec.check_set_params,
    ec.check_parameters_default_constructible,
    ec.check_estimator_cloneable,
    ec.check_estimator_repr,
    ec.check_do_not_raise_errors_in_init_or_set_params,
    ec.check_mixin_order,
]


@pytest.mark.parametrize("check", NO_DATA_CHECKS, ids=lambda c: c.__name__)
def test_scikit_learn_checks_without_data(check):
    check("Model", Model())


def fitted_attributes(m: Model) -> list[str]:
    """scikit-learn's rule (`check_is_fitted`, which also wants its tags): attributes ending in '_'."""
    return [k for k in vars(m) if k.endswith("_") and not k.startswith("__")]


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(7)
    n = 300
    xy = rng.uniform([-150, -50], [150, 50], (n, 2))
    depth = rng.uniform(1.0, 6.0, n)
    y = 0.8 + 0.3 * np.sin(xy[:, 0] / 50.0) + 0.1 * depth + 0.05 * rng.standard_normal(n)
    return {"position": xy, "depth": depth, "t": np.arange(n) * 0.5}, y


def _terms():
    specs = ["const", "gp(position, matern32)", "linear(depth)", "power(depth)"]
    return [build_term(parse_term(s, is_circular), is_circular) for s in specs]


def test_fit_returns_self_and_leaves_its_parameters_alone(data):
    X, y = data
    m = Model(_terms(), max_basis=100, hyper_spacing_s=2.0, init=None, memory=DesignCache())
    before = joblib.hash(m.get_params())
    assert m.fit(X, y) is m
    # scikit-learn's check_estimators_overwrite_params: the constructor's arguments, Term objects included,
    # are exactly what they were (fit works on copies; it sets up and may grow its own)
    assert joblib.hash(m.get_params()) == before
    assert all(a is not b for a, b in zip(m.terms, m.terms_, strict=True))


def test_fit_adds_only_fitted_or_private_attributes(data):
    X, y = data
    m = Model(_terms())
    public_before = {k for k in vars(m) if not k.startswith("_")}
    m.fit(X, y)
    added = {k for k in vars(m) if not k.startswith("_")} - public_before
    assert added and all(k.endswith("_") for k in added), added
    for name in ("design_", "y_scale_", "h_slices_", "terms_", "theta_"):
        assert name in vars(m)


def test_unfitted_model_says_so(data):
    X, _ = data
    m = Model()
    assert not fitted_attributes(m)
    with pytest.raises(NotFittedError, match="fit"):
        m.predict(X)
    # scikit-learn's check_estimators_unfitted accepts either base class
    assert issubclass(NotFittedError, ValueError) and issubclass(NotFittedError, AttributeError)


def test_fit_is_idempotent_and_clone_is_unfitted(data):
    X, y = data
    m = Model(_terms()).fit(X, y)
    assert fitted_attributes(m)
    first = m.predict(X)
    assert np.array_equal(m.fit(X, y).predict(X), first)
    c = clone(m)
    assert not fitted_attributes(c)
    assert np.allclose(c.fit(X, y).predict(X), first)


def test_set_params_takes_effect_at_the_next_fit(data):
    X, y = data
    m = Model(["const", "gp(position, matern32)"]).fit(X, y)
    assert m.set_params(terms=["const", "gp(position, matern32)", "linear(depth)"]) is m
    assert "linear(depth)" not in m.params_
    assert "linear(depth)" in m.fit(X, y).params_
    with pytest.raises(ValueError, match="invalid parameter"):
        m.set_params(no_such=1)


def test_extended_shares_no_term_with_either_model(data):
    X, y = data
    base = Model(["const", "gp(position, matern32)"], max_basis=100).fit(X, y)
    term = build_term(parse_term("depth", is_circular), is_circular)
    state = copy.deepcopy(vars(term))
    ext = base.extended(term, X, y)
    assert vars(term).keys() == state.keys()  # not set up by extended
    base_ids = {id(t) for t in base.terms_}
    assert not base_ids & {id(t) for t in ext.terms_}
    assert not base_ids & {id(t) for t in ext.terms}
    assert term not in ext.terms_
    assert ext.max_basis == base.max_basis and ext.hyper_spacing_s == base.hyper_spacing_s


def test_pickled_model_predicts_the_same(data):
    X, y = data
    m = Model(_terms()).fit(X, y)
    again = pickle.loads(pickle.dumps(m))
    assert np.array_equal(again.predict(X), m.predict(X))


def _rows(X: dict, rows: np.ndarray) -> dict:
    return {k: v[rows] for k, v in X.items()}


@pytest.mark.parametrize(
    "splitter",
    [KFold(4, shuffle=True, random_state=0), GroupKFold(3)],
    ids=["KFold", "GroupKFold"],
)
def test_clone_then_a_splitter_fits_each_fold_on_its_own_rows(data, splitter):
    """The hyperparameters come from samples `hyper_spacing_s` apart in the fold's own times, so a clone
    fitted on a fold's rows is the model of those rows: the same as a model built for them directly."""
    X, y = data
    m = Model(
        ["const", "gp(position, matern32)", "linear(depth)"], max_basis=64, hyper_spacing_s=2.0
    )
    groups = (X["position"][:, 0] // 100).astype(int)
    for train, test in splitter.split(y, y, groups if isinstance(splitter, GroupKFold) else None):
        fold = clone(m).fit(_rows(X, train), y[train])
        direct = Model(m.terms, max_basis=64, hyper_spacing_s=2.0).fit(_rows(X, train), y[train])
        np.testing.assert_allclose(
            fold.predict(_rows(X, test)), direct.predict(_rows(X, test)), rtol=0, atol=1e-10
        )
        # and its hyperparameter rows are rows of the fold: one per 2 s of the fold's times
        t = X["t"][train]
        rows = spaced_rows(t, 2.0, min_rows=1)
        assert rows is not None and rows.max() < len(train)
        assert np.all(np.diff(np.floor((t[rows] - t.min()) / 2.0)) >= 1)


def test_warm_start_and_design_cache_are_constructor_parameters(data):
    """`fit` takes data only: a warm start (`init`, `optimize`) and the Gram cache (`memory`) are parameters,
    and two models of the same features on the same inputs share one design through the cache."""
    X, y = data
    cache = DesignCache()
    first = Model(["const", "gp(position, matern32)"], memory=cache).fit(X, y)
    again = Model(["const", "gp(position, matern32)"], init=first.theta_, optimize=False)
    np.testing.assert_allclose(again.fit(X, y).predict(X), first.predict(X), atol=1e-10)
    other = Model(["const", "gp(position, matern32)"], memory=cache).fit(X, -2.0 * y)
    assert other.design_ is first.design_
    np.testing.assert_allclose(other.predict(X), -2.0 * first.predict(X), rtol=1e-6, atol=1e-6)
    with pytest.raises(TypeError):
        Model().fit(X, y, init=first.theta_)
