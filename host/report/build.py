"""The survey report: one self-contained HTML file (images embedded as base64 PNG).

`build_report` runs the functions in `SECTIONS` in order; each takes the `ReportContext` and returns its HTML
parts. A new section is one function and one line in `SECTIONS`.
"""

from __future__ import annotations

import functools
import html
import importlib.util
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from forcemap.host.extras import install_hint
from forcemap.host.gis.grid import MapGrid, evaluate, make_grid, project
from forcemap.host.progress import note
from forcemap.host.report.diagnose_section import rounds_section
from forcemap.host.report.map_figure import grid_figure, img, point_figure
from forcemap.host.report.mission_section import mission_section
from forcemap.host.report.reference_section import reference_section
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.fits import plots
from forcemap.host.workbench.fits.fit import calibrated, latest_terms, map_terms, refit_or_restore
from forcemap.host.workbench.fits.workspace import load_diagnoses, load_history, workspace_dir
from forcemap.host.workbench.survey import data_quality
from forcemap.host.workbench.survey.table import Survey, unit_of
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.validation.cv import blocked_folds
from forcemap.host.workbench.validation.failures import failure_summary

CSS = """
body { font-family: sans-serif; max-width: 1100px; margin: 1em auto; color: #222; }
h1 { font-size: 1.5em; } h2 { border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 0.9em; } td, th { border: 1px solid #ccc; padding: 3px 6px; }
th { background: #eee; } img { max-width: 100%; } img.map { width: 100%; } .found { color: #060; font-weight: bold; }
.none { color: #555; } .small { font-size: 0.85em; color: #555; }
"""

MAPPED = (
    ("current_speed", "current speed (m/s)", True),
    ("wind_speed", "wind speed (m/s)", True),
    ("depth", "depth (m)", False),
)


@dataclass
class ReportContext:
    """What every section may read: the table, its survey, the workspace's history and diagnoses."""

    table: Path
    survey: Survey
    ws: Path
    history: list[dict]
    diagnoses: dict[str, dict]
    progress: bool = True
    # fitted models by (target, terms), shared between sections
    models: dict[tuple[str, tuple[str, ...]], SurveyModel] = field(default_factory=dict)

    def model(self, target: str, terms: list[str]) -> SurveyModel:
        """The fitted model of `target` with `terms`, with its predictive band's calibration: rebuilt from
        the workspace's saved fit when there is one, else fitted; once per report."""
        key = (target, tuple(terms))
        if key not in self.models:
            self.models[key] = calibrated(
                refit_or_restore(self.ws, self.history, self.survey, target, terms, self.progress)
            )
        return self.models[key]

    @functools.cached_property
    def frame(self) -> tuple[MapGrid, tuple[np.ndarray, np.ndarray], list[str]]:
        """The one grid, frame and origin of every map in the report (`report_grid`), and the track on it."""
        return report_grid(self.survey)

    def track_of(self, survey: Survey) -> tuple[np.ndarray, np.ndarray]:
        """The samples of `survey` (the report's, or a model's rows) in the maps' frame."""
        grid = self.frame[0]
        if grid.epsg == 0:
            return survey.columns["x"], survey.columns["y"]
        return project(grid, survey.columns["lat"], survey.columns["lon"])


def header_section(ctx: ReportContext) -> list[str]:
    survey = ctx.survey
    dur = float(survey.trel.max()) / 60.0
    span = np.ptp(survey.xy, axis=0)
    parts = [
        f"<h1>forcemap survey report: {html.escape(ctx.table.name)}</h1>",
        f"<p>{survey.n} samples over {dur:.0f} min, an area of {span[0]:.0f} m x {span[1]:.0f} m centred on "
        f"{survey.lat0:.5f}, {survey.lon0:.5f}. Generated {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.</p>",
    ]
    parts += [f"<p class=small>note: {html.escape(n)}</p>" for n in survey.notes]
    return parts


def data_quality_section(ctx: ReportContext) -> list[str]:
    """Problems of the log itself, ahead of every map and candidate: source conflicts, spikes, latency,
    quantisation (host/workbench/survey/data_quality.py)."""
    targets = [t for t, _, _ in MAPPED] + [h["target"] for h in ctx.history] + list(ctx.diagnoses)
    targets = [t for t in dict.fromkeys(targets) if t in ctx.survey.columns]
    found = data_quality.findings(ctx.survey, targets)
    parts = ["<h2>Data quality: before the physics</h2>"]
    if not found:
        return parts + [
            "<p>No source conflict, spike, latency or coarse position grid found in the log.</p>"
        ]
    parts.append(
        "<p>Problems of the log itself: fix them first, or the maps and the diagnosis explain the "
        "log, not the water.</p><table><tr><th>kind</th><th>finding</th><th>what to do</th></tr>"
    )
    parts += [
        f"<tr><td>{html.escape(f.kind)}</td><td>{html.escape(f.text)}</td>"
        f"<td class=small>{html.escape(f.advice)}</td></tr>"
        for f in found
    ]
    parts.append("</table>")
    return parts


def qa_section(ctx: ReportContext) -> list[str]:
    """`forcemap check`'s grades of the log (host/qa/): per category the verdict, number and fix."""
    from forcemap.host.qa.report import check_table

    rep = check_table(ctx.table)
    parts = [
        f"<h2>Quality: {rep.verdict}</h2>",
        "<p>Each category graded as USGS QRev grades a discharge measurement (docs/QA.md); the "
        "estimates applied at import are marked.</p>",
        "<table><tr><th>category</th><th>verdict</th><th>finding</th><th>fix</th></tr>",
    ]
    for cat, fs in rep.by_category().items():
        for f in fs:
            mark = " (applied)" if f.applied else ""
            parts.append(
                f"<tr><td>{html.escape(cat.replace('_', ' '))}</td><td>{f.verdict}</td>"
                f"<td>{html.escape(f.message)}</td><td class=small>{html.escape(f.fix)}{mark}</td></tr>"
            )
    return parts + ["</table>"]


def measurements_section(ctx: ReportContext) -> list[str]:
    parts = ["<h2>Measurements</h2>"]
    grid, track, _ = ctx.frame
    for col, label, _ in MAPPED:
        if col in ctx.survey.columns:
            values = ctx.survey.columns[col]
            fig = point_figure(grid, track, values, f"measured {col}", label)
            parts.append(img(fig, col, "map"))
    return parts


def report_grid(survey: Survey) -> tuple[MapGrid, tuple[np.ndarray, np.ndarray], list[str]]:
    """The grid of `forcemap grid` at a resolution giving ~120 cells along the survey's longer side, in
    its UTM zone (the local frame where pyproj is not installed or UTM cannot map it), and the track on it."""
    span = float(np.ptp(survey.xy, axis=0).max())
    resolution = max(1.0, float(f"{span / 120:.1g}"))
    if importlib.util.find_spec("pyproj") is not None:
        try:
            grid = make_grid(survey, resolution)
            return grid, project(grid, survey.columns["lat"], survey.columns["lon"]), grid.notes
        except WorkbenchError as exc:
            why = str(exc)
    else:
        why = f"pyproj is not installed ({install_hint('gis')})"
    grid = make_grid(survey, resolution, utm=False)
    return (
        grid,
        (survey.columns["x"], survey.columns["y"]),
        [f"maps in the survey's local frame: {why}"],
    )


def maps_section(ctx: ReportContext) -> list[str]:
    survey = ctx.survey
    grid, track, notes = ctx.frame
    parts = [
        "<h2>Model maps: mean and uncertainty</h2>",
        "<p>Wind and current are modelled through their east/north components: arrows show the modelled "
        "velocity of the medium (where it moves to), colour its speed. Depth is shown with contours. Terms in "
        "covariates are evaluated at typical values (depth from its own map, time at mid-survey). "
        f"The grid is the one <code>forcemap grid</code> writes ({html.escape(grid.zone_name)}, "
        f"{grid.resolution:g} m cells; cells farther than {grid.max_distance:.0f} m from every sample are "
        "left blank, and so are a map's cells beyond its cross-validation's reach or where its predictive "
        "sd exceeds the measured values' own); the arrow marks true north. The uncertainty is the "
        "<b>predictive</b> sd: what a new measurement at that point would differ from the mean by (the "
        "mean's uncertainty plus the measurement noise), widened where the blocked cross-validation "
        "shows the model's own band covering less than 95 % of held-out samples.</p>",
    ]
    parts += [f"<p class=small>note: {html.escape(n)}</p>" for n in notes]
    for target, label, _ in MAPPED:
        try:
            terms = map_terms(survey, ctx.history, target)
            note(f"report: mapping {target} ({' + '.join(terms)}) ...", ctx.progress)
            layer = evaluate(grid, ctx.model(target, terms))
        except WorkbenchError as exc:
            parts.append(
                f"<p class=small>{html.escape(target)}: not mapped ({html.escape(str(exc))})</p>"
            )
            continue
        name = target.split("_")[0]
        parts.append(f"<h3>{html.escape(name)}: {html.escape(' + '.join(terms))}</h3>")
        if layer.calibration is not None:
            parts.append(f"<p>{html.escape(layer.calibration.line())}.</p>")
        parts += [f"<p class=small>note: {html.escape(n)}</p>" for n in layer.notes]
        parts.append(img(grid_figure(grid, layer, track, label), target, "map"))
        if layer.datum:
            parts.append(f"<p class=small>{html.escape(layer.datum)}.</p>")
    return parts


def residuals_section(ctx: ReportContext) -> list[str]:
    targets = list(dict.fromkeys([h["target"] for h in ctx.history] + list(ctx.diagnoses)))
    if not targets:
        return []
    parts = [
        "<h2>Residuals: where the models fail</h2>",
        "<p>Held-out residuals from spatially blocked 5-fold cross-validation of the latest fit of each "
        "target (measured minus predicted).</p>",
    ]
    for target in targets:
        parts += _target_residuals(ctx, target)
    return parts


def _target_residuals(ctx: ReportContext, target: str) -> list[str]:
    try:
        terms = latest_terms(ctx.history, target)
        note(f"report: residuals of {target} ...", ctx.progress)
        sm = ctx.model(target, terms)
        survey = sm.survey  # the rows the model is fitted on: the target's spikes left out
        cv = sm.cv_ if sm.cv_ is not None else sm.cv(blocked_folds(survey.xy)[0])
    except WorkbenchError as exc:
        return [f"<p class=small>{html.escape(target)}: not modelled ({html.escape(str(exc))})</p>"]
    u = unit_of(target)
    unit = f" {u}" if u else ""
    parts = [
        f"<h3>{html.escape(target)}: {html.escape(' + '.join(terms))}</h3>",
        f"<p>CV RMSE {cv.rmse:.4g}{unit}, MAE {cv.mae:.4g}{unit}, the model's own predictive 95 % band "
        f"covers {cv.coverage95:.1%}"
        + (f"; {html.escape(sm.calibration.line())}" if sm.calibration else "")
        + ".</p><ul>",
    ]
    parts += [f"<li>{html.escape(s)}</li>" for s in failure_summary(survey, cv.error, unit)]
    parts.append("</ul>")
    title = f"{target}: held-out residuals"
    label = f"residual ({u})" if u else "residual"
    fig = point_figure(ctx.frame[0], ctx.track_of(survey), cv.error, title, label, "RdBu_r", True)
    parts.append(img(fig, "residual map", "map"))
    extra = {k: v for k, v in sm.X.items() if np.ndim(v) == 1}  # position, a reference: not one column
    title = f"{target}: residual against covariates"
    parts.append(
        img(plots.residual_panels(survey, cv.error, extra, title, target), "residual panels")
    )
    return parts


def diagnoses_section(ctx: ReportContext) -> list[str]:
    parts = ["<h2>Missing effects, ranked</h2>"]
    if not ctx.diagnoses:
        parts.append(
            f"<p>No diagnosis yet: run <code>forcemap diagnose {html.escape(ctx.table.name)} --target TARGET</code>.</p>"
        )
    for target, d in ctx.diagnoses.items():
        parts += _diagnosis(target, d)
    return parts


def _diagnosis(target: str, d: dict) -> list[str]:
    base = d["baseline"]
    unit = f" {u}" if (u := unit_of(target)) else ""
    parts = [
        f"<h3>{html.escape(target)} (model {html.escape(' + '.join(base['terms']))}, blocked-CV RMSE "
        f"{base['cv_rmse']:.4g}{unit}, pooled over 3 assignments of the blocks to folds)</h3>"
    ]
    if d.get("missing_effect_found") and d["candidates"]:
        parts.append(
            f"<p class=found>missing effect found: {html.escape(d['candidates'][0]['covariate'])}</p>"
        )
    else:
        parts.append("<p class=none>no missing effect found</p>")
    parts.append(
        "<table><tr><th>#</th><th>covariate</th><th>CV RMSE</th><th>improvement</th><th>explanation</th></tr>"
    )
    for i, c in enumerate(d["candidates"][:10], 1):
        parts.append(
            f"<tr><td>{i}</td><td>{html.escape(c['covariate'])}</td><td>{c['cv_rmse']:.4g}{unit}</td>"
            f"<td>{c['improvement']:+.1%}</td><td class=small>{html.escape(c['explanation'])}</td></tr>"
        )
    parts.append("</table>")
    return parts


def history_section(ctx: ReportContext) -> list[str]:
    parts = ["<h2>Error history</h2>"]
    if not ctx.history:
        return parts + ["<p>No fits recorded yet.</p>"]
    parts.append(
        "<table><tr><th>fit</th><th>target</th><th>terms</th><th>CV RMSE</th><th>MAE</th><th>model's 95 % band covers</th></tr>"
    )
    for h in ctx.history:
        unit = f" {u}" if (u := unit_of(h["target"])) else ""
        parts.append(
            f"<tr><td>{h['fit']}</td><td>{html.escape(h['target'])}</td><td>{html.escape(' + '.join(h['terms']))}</td>"
            f"<td>{h['cv_rmse']:.4g}{unit}</td><td>{h['cv_mae']:.4g}{unit}</td><td>{h['coverage95']:.1%}</td></tr>"
        )
    parts.append("</table>")
    parts.append(img(plots.history_figure(ctx.history), "error history"))
    return parts


def rounds_and_advice_section(ctx: ReportContext) -> list[str]:
    """Each diagnosis round with the error falling, and the survey advice (host.workbench.report_diagnose)."""
    return rounds_section(ctx.diagnoses)


def plan_section(ctx: ReportContext) -> list[str]:
    """`forcemap plan`'s newest plan: intended, predicted and flown tracks (host.plan.report_section)."""
    return mission_section(ctx.table, ctx.survey)


Section = Callable[[ReportContext], list[str]]

SECTIONS: list[Section] = [
    header_section,
    qa_section,
    data_quality_section,
    measurements_section,
    maps_section,
    reference_section,
    residuals_section,
    diagnoses_section,
    rounds_and_advice_section,
    history_section,
    plan_section,
]


def build_report(
    table: Path, survey: Survey, progress: bool = True, sections: list[Section] | None = None
) -> str:
    """The report's HTML: every section of `sections` (default `SECTIONS`) in order."""
    ws = workspace_dir(table)
    ctx = ReportContext(table, survey, ws, load_history(ws), load_diagnoses(ws), progress)
    parts: list[str] = []
    for section in SECTIONS if sections is None else sections:
        parts += section(ctx)
    return page(table.name, parts)


def page(name: str, parts: list[str]) -> str:
    body = "\n".join(parts)
    return f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>forcemap report: {html.escape(name)}</title><style>{CSS}</style></head><body>\n{body}\n</body></html>\n"
