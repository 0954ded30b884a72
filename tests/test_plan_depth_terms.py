"""`plan` maps the current with every term of the latest fit it can evaluate along a future track: a
depth term is evaluated on the survey's depth map, not dropped (issue 33). On a synthetic river whose
current depends on depth in closed form (`bench.synth_survey`, `depth_current`), the plan's current map
with the depth term is closer to the true current along the surveyed lines than a position-only map."""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.cli import main
from forcemap.host.plan.maps import fit_field, plannable_terms, survey_maps
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.survey.table import load_survey
from scipy.spatial import cKDTree

from bench.synth_survey import LAT0, LON0, current_field, make_survey


def test_what_a_future_track_knows():
    keep, drop = plannable_terms(
        ["gp(position, matern32)", "gp(depth, matern32)", "linear(heading)", "gp(t, se)"]
    )
    assert keep == ["gp(position, matern32)", "gp(depth, matern32)", "gp(t, se)"]
    assert drop == ["linear(heading)"]


def _truth_error(survey, field, near):
    ny, nx = field.east.shape
    GX, GY = np.meshgrid(
        field.x0 + np.arange(nx) * field.step, field.y0 + np.arange(ny) * field.step
    )
    lat, lon = LocalFrame(survey.lat0, survey.lon0).to_latlon(GX.ravel(), GY.ravel())
    tx, ty = LocalFrame(LAT0, LON0).to_local(lat, lon)
    te, tn = current_field(tx, ty, 0.0, {"depth_current"}, 1.0)
    err = np.hypot(field.east.ravel() - te, field.north.ravel() - tn)
    return float(np.sqrt(np.mean(err[near] ** 2)))


@pytest.mark.slow
def test_the_depth_term_is_kept_and_maps_the_current_closer_to_the_truth(tmp_path):
    csv = make_survey("river", ["depth_current"], 1, 1800, tmp_path)
    fit = ["fit", str(csv), "--target", "current_speed", "--no-plots", "--quiet"]
    assert main([*fit, "--effects", "depth"]) == 0
    survey = load_survey(csv)
    x, y = survey.xy[:, 0], survey.xy[:, 1]
    bounds = (x.min() - 20, x.max() + 20, y.min() - 20, y.max() + 20)
    maps = survey_maps(csv, survey, bounds, progress=False)
    assert any("depth" in t for t in maps.current.terms), maps.current.terms
    assert any("depth map" in n for n in maps.notes) and not any(
        "left out" in n for n in maps.notes
    )
    flat = fit_field(survey, "current", ["gp(position, matern32)"], bounds)
    ny, nx = flat.east.shape
    GX, GY = np.meshgrid(flat.x0 + np.arange(nx) * flat.step, flat.y0 + np.arange(ny) * flat.step)
    dist = cKDTree(survey.xy).query(np.column_stack([GX.ravel(), GY.ravel()]))[0]
    near = dist < 10.0  # along the surveyed lines, where a plan's lines run
    with_depth, without = _truth_error(survey, maps.current, near), _truth_error(survey, flat, near)
    assert with_depth < 0.8 * without, (with_depth, without)
