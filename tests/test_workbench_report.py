"""The report: sections added by one line, and maps rebuilt from the workspace's saved fits, not refitted."""

from __future__ import annotations

import json

import numpy as np
import pytest
from forcemap.host.gis.grid import make_grid
from forcemap.host.report import build as report
from forcemap.host.workbench.engine.model import Model
from forcemap.host.workbench.fits.fit import fit_target, record, refit_or_restore, saved_model
from forcemap.host.workbench.fits.workspace import load_history, workspace_dir
from forcemap.host.workbench.survey.table import load_survey

from bench.synth_survey import make_survey

BASE = ["const", "gp(position, matern32)"]


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    table = make_survey("river", ["depth_current"], 5, 900.0, tmp_path_factory.mktemp("survey"))
    survey = load_survey(table)
    results = {}
    for target, terms in (("depth", BASE), ("current_speed", [*BASE, "depth"])):
        results[target] = fit_target(survey, target, terms, progress=False)
        record(table, results[target])
    return table, results


def _grid(survey):
    return make_grid(survey, 20.0, utm=False).local_xy


def test_saved_fit_rebuilds_the_same_map_without_the_optimiser(fitted, monkeypatch):
    table, results = fitted
    survey = load_survey(table)  # a fresh survey: nothing shared with the fits above
    ws = workspace_dir(table)
    history = load_history(ws)
    assert [h["target"] for h in history] == ["depth", "current_speed"]

    def no_optimiser(self, theta, search):
        raise AssertionError("the optimiser ran")

    monkeypatch.setattr(Model, "_optimize", no_optimiser)
    sm = refit_or_restore(ws, history, survey, "depth", BASE, progress=False)
    fitted_sm = results["depth"].model
    assert np.array_equal(sm.primary.theta_, fitted_sm.primary.theta_)
    assert sm.primary.n_basis_ == fitted_sm.primary.n_basis_
    grid = _grid(survey)
    a, b = sm.predict_grid(grid), fitted_sm.predict_grid(grid)
    assert np.max(np.abs(a["mean"] - b["mean"])) < 1e-9 * np.max(np.abs(b["mean"]))
    assert np.allclose(a["std"], b["std"], rtol=1e-9, atol=0)

    # a vector target: its primary, its flow frame and its other component from the saved fit
    terms = history[1]["terms"]
    sm = refit_or_restore(ws, history, survey, "current_speed", terms, progress=False)
    monkeypatch.undo()
    assert np.array_equal(sm.primary.theta_, results["current_speed"].model.primary.theta_)
    a, b = sm.predict_grid(grid), results["current_speed"].model.predict_grid(grid)
    assert np.allclose(a["speed"], b["speed"], rtol=1e-6, atol=1e-9)


def test_a_saved_fit_of_another_survey_is_refitted(fitted):
    table, _ = fitted
    ws = workspace_dir(table)
    entry = load_history(ws)[0]
    survey = load_survey(table)
    assert saved_model(ws, entry, survey) is not None
    model = json.loads((ws / entry["model_file"]).read_text())
    other = {**entry, "model_file": "models/of-another-survey.json"}
    (ws / other["model_file"]).write_text(json.dumps({**model, "n": model["n"] - 1}))
    assert saved_model(ws, other, survey) is None
    entry = other
    sm = refit_or_restore(ws, [entry], survey, "depth", BASE, progress=False)
    assert hasattr(sm.primary, "n_iter_")  # fitted by the optimiser
    assert sm.primary.theta_ == pytest.approx(model["theta"], rel=1e-6, abs=1e-9)


def test_a_section_is_one_function(fitted):
    table, _ = fitted
    survey = load_survey(table)

    def mission_section(ctx: report.ReportContext) -> list[str]:
        return [f"<h2>Mission</h2><p>{ctx.survey.n} samples, {len(ctx.history)} fits</p>"]

    html = report.build_report(
        table, survey, progress=False, sections=[report.header_section, mission_section]
    )
    assert f"<p>{survey.n} samples, 2 fits</p>" in html
    assert "<h2>Measurements</h2>" not in html
    assert html.index("<h1>") < html.index("<h2>Mission</h2>") < html.index("</body>")
    assert report.SECTIONS[0] is report.header_section
    assert (
        report.plan_section in report.SECTIONS
        and report.rounds_and_advice_section in report.SECTIONS
    )


def test_maps_are_the_grid_of_forcemap_grid_with_scale_and_north(fitted, tmp_path):
    import base64
    import re

    from forcemap.host.report.map_figure import figsize, nice_length

    table, _ = fitted
    survey = load_survey(table)
    grid, track, _ = report.report_grid(survey)
    assert grid.epsg == 32617  # 33.95 N, 81.05 W
    assert np.allclose(track[0], make_grid(survey, grid.resolution).easting[0], atol=1e3)
    # the survey is 600 m x 150 m: two panels stacked, each the page's width
    (w, h), side = figsize(grid)
    assert not side and w == 11.0 and h < 11.0
    assert nice_length(600.0) == 100.0 and nice_length(4200.0) == 500.0
    html = report.page("t", report.maps_section(report_context(table, survey)))
    pngs = re.findall(r'alt="(\w+)" src="data:image/png;base64,([^"]+)"', html)
    assert [a for a, _ in pngs] == ["current_speed", "wind_speed", "depth"]
    (tmp_path / "depth.png").write_bytes(base64.b64decode(pngs[-1][1]))
    assert "UTM zone 17N" in html


def report_context(table, survey):
    ws = workspace_dir(table)
    return report.ReportContext(table, survey, ws, load_history(ws), {}, False)
