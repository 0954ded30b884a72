"""The maps' standard deviation from the tables (`fourier.waves`, `linear_form`, `quadratic_form`: the fast
block's features never formed) equals the direct phi' Sigma phi = |L^-1 (s * phi)|^2 over the features, on a
masked grid, for a scalar target and for each component of a vector target with a covariate effect (so the
model also has blocks outside the fast one and their covariances with it)."""

from __future__ import annotations

import math

import forcemap
import numpy as np
import pytest
from forcemap.host.gis.grid import evaluate, make_grid
from forcemap.host.workbench.engine.hypersearch import term_inputs
from forcemap.host.workbench.engine.model import Model
from forcemap.host.workbench.targets.survey_fits import frame_direction, grid_inputs
from scipy import linalg

from bench.synth_survey import make_survey

REL = 1e-9


def direct(model: Model, X: dict) -> tuple[np.ndarray, np.ndarray]:
    """Mean and latent sd over the full features: the textbook products, no tables."""
    post = model.posterior_
    Phi = np.hstack(model.features(X))
    mean_part = 0.0
    if model.mean_terms_:
        mean_part = model._mean([term_inputs(t, X) for t in model.mean_terms_], model.theta_)
    mu = Phi @ post["mu"] * model.y_scale_ + mean_part
    V = linalg.solve_triangular(post["L"], (Phi * post["s"]).T, lower=True)
    return mu, np.sqrt((V**2).sum(axis=0)) * model.y_scale_


def assert_close(got, want, what):
    err = np.abs(got - want).max() / np.abs(want).max()
    assert err < REL, f"{what}: {err:.1e} relative"


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    d = tmp_path_factory.mktemp("gisvar")
    return forcemap.read_survey(make_survey("river", ["depth_current"], 5, 1500.0, d))


@pytest.fixture(scope="module")
def grid(survey):
    g = make_grid(survey.table, 3.0, max_distance=12.0)
    assert 0.2 < g.mask.mean() < 0.95  # a masked grid: some cells are left out
    return g


def test_a_scalar_maps_sd_is_the_direct_quadratic_form(survey, grid):
    fit = survey.fit("depth")
    model = fit.model_.primary
    assert model.design_.fast is not None  # the tables' path, not the direct one
    xy = grid.local_xy[grid.mask.ravel()]
    mu, sd = model.predict({"position": xy}, return_std=True)
    mu_d, sd_d = direct(model, {"position": xy})
    assert_close(mu, mu_d, "mean")
    assert_close(sd, sd_d, "sd")
    layer = evaluate(grid, fit.model_)
    assert np.isnan(layer.bands["sd"][~grid.mask]).all()
    # the maps' sd is the predictive one (latent and noise variance, times the CV's factor); mean_sd the latent
    k = fit.model_.sd_scale
    assert k > 0.0
    kept = np.isfinite(layer.bands["mean"][grid.mask])
    assert kept.mean() > 0.8  # few cells left blank as untested or vague
    pred = k * np.hypot(sd_d, model.noise_std_)
    assert_close(layer.bands["sd"][grid.mask][kept], pred[kept], "the sd band")
    assert_close(layer.bands["mean_sd"][grid.mask][kept], sd_d[kept], "the mean_sd band")
    assert_close(layer.bands["mean"][grid.mask][kept], mu_d[kept], "the mean band")


def test_a_vectors_component_sds_are_the_direct_quadratic_forms(survey, grid):
    fit = survey.fit("current_speed", effects=["depth"])
    sm = fit.model_
    assert sm.secondary is not None and sm.primary.design_.fast is not None
    _, slow = sm.primary.design_.fast_cols
    assert len(slow) > 1  # the constant and the depth effect: covariances outside the fast block
    xy = grid.local_xy[grid.mask.ravel()]
    X = grid_inputs(sm.survey, {i for s in sm.term_specs for i in s.inputs}, xy)
    comps = []
    for model, inputs in ((sm.primary, X), (sm.secondary, {"position": xy})):
        mu, sd = model.predict(inputs, return_std=True)
        mu_d, sd_d = direct(model, inputs)
        assert_close(mu, mu_d, "a component's mean")
        assert_close(sd, sd_d, "a component's sd")
        # a new measurement's spread: the component's latent and noise variance
        comps.append((mu_d, np.hypot(sd_d, model.noise_std_)))
    (ma, sa), (mc, sc) = comps if sm.primary_is_along else comps[::-1]
    ue, un = frame_direction(sm.survey, sm.vector, xy)
    bands = evaluate(grid, sm).bands
    assert np.isnan(bands["east_sd"][~grid.mask]).all()
    kept = np.isfinite(bands["east"][grid.mask])
    assert kept.mean() > 0.8
    k = sm.sd_scale

    def check(band, want):
        assert_close(bands[band][grid.mask][kept], want[kept], band)

    check("east_sd", k * np.hypot(sa * ue, sc * un))
    check("north_sd", k * np.hypot(sa * un, sc * ue))
    check("east", ma * ue - mc * un)
    check("north", ma * un + mc * ue)
    assert math.isfinite(float(np.nanmax(bands["speed_sd"])))  # a speed's sd is its draws' spread
