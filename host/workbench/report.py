"""The survey report: one self-contained HTML file (images embedded as base64 PNG)."""

from __future__ import annotations

import base64
import html
import time
from pathlib import Path

import numpy as np
from forcemap.host.plan.report_section import mission_section
from forcemap.host.workbench import clock_offset, plots
from forcemap.host.workbench.cv import blocked_folds
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.failures import failure_summary
from forcemap.host.workbench.progress import note
from forcemap.host.workbench.report_diagnose import rounds_section
from forcemap.host.workbench.spec import BASELINE
from forcemap.host.workbench.table import Survey
from forcemap.host.workbench.targets import SurveyModel
from forcemap.host.workbench.workspace import load_diagnoses, load_history, workspace_dir

CSS = """
body { font-family: sans-serif; max-width: 1100px; margin: 1em auto; color: #222; }
h1 { font-size: 1.5em; } h2 { border-bottom: 1px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: 0.9em; } td, th { border: 1px solid #ccc; padding: 3px 6px; }
th { background: #eee; } img { max-width: 100%; } .found { color: #060; font-weight: bold; }
.none { color: #555; } .small { font-size: 0.85em; color: #555; }
"""


def _img(fig, alt: str) -> str:
    data = base64.b64encode(plots.png_bytes(fig)).decode()
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def _latest_terms(history: list[dict], target: str) -> list[str]:
    for h in reversed(history):
        if h["target"] == target:
            return h["terms"]
    return list(BASELINE)


def _map_terms(survey: Survey, history: list[dict], target: str) -> list[str]:
    """The target's latest terms; a clock offset fitted for any aspect of the same vector (wind_dir, say)
    corrects the whole vector, so the map of its speed uses it too."""
    terms = _latest_terms(history, target)
    vt = survey.vector_target(target)
    if vt is None or clock_offset.split_terms(terms)[1] is not None:
        return terms
    for h in reversed(history):
        other = survey.vector_target(h["target"])
        if other is not None and other.prefix == vt.prefix:
            offset = [t for t in h["terms"] if clock_offset.split_terms([t])[1] is not None]
            if offset:
                return terms + offset
    return terms


def build_report(table: Path, survey: Survey, progress: bool = True) -> str:
    ws = workspace_dir(table)
    history = load_history(ws)
    diagnoses = load_diagnoses(ws)
    parts = [f"<h1>forcemap survey report: {html.escape(table.name)}</h1>"]
    dur = float(survey.trel.max()) / 60.0
    span = np.ptp(survey.xy, axis=0)
    parts.append(
        f"<p>{survey.n} samples over {dur:.0f} min, an area of {span[0]:.0f} m x {span[1]:.0f} m centred on "
        f"{survey.lat0:.5f}, {survey.lon0:.5f}. Generated {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.</p>"
    )
    for n in survey.notes:
        parts.append(f"<p class=small>note: {html.escape(n)}</p>")

    parts.append("<h2>Measurements</h2>")
    for col, label in (
        ("current_speed", "current speed (m/s)"),
        ("wind_speed", "wind speed (m/s)"),
        ("depth", "depth (m)"),
    ):
        if col in survey.columns:
            parts.append(
                _img(plots.scatter_map(survey, survey.columns[col], f"measured {col}", label), col)
            )

    parts.append("<h2>Model maps: mean and uncertainty</h2>")
    parts.append(
        "<p>Wind and current are modelled through their east/north components: arrows show the modelled "
        "velocity of the medium (where it moves to), colour its speed. Depth is shown with contours. Terms in "
        "covariates are evaluated at typical values (depth from its own map, time at mid-survey).</p>"
    )
    X, Y, mask = plots.map_grid(survey)
    grid = np.column_stack([X.ravel(), Y.ravel()])
    for target, label, arrows in (
        ("current_speed", "current speed (m/s)", True),
        ("wind_speed", "wind speed (m/s)", True),
        ("depth", "depth (m)", False),
    ):
        try:
            terms = _map_terms(survey, history, target)
            note(f"report: mapping {target} ({' + '.join(terms)}) ...", progress)
            sm = SurveyModel(survey, target, terms).fit()
            pred = sm.predict_grid(grid)
        except WorkbenchError as exc:
            parts.append(
                f"<p class=small>{html.escape(target)}: not mapped ({html.escape(str(exc))})</p>"
            )
            continue
        parts.append(
            f"<h3>{html.escape(target.split('_')[0])}: {html.escape(' + '.join(terms))}</h3>"
        )
        parts.append(
            _img(
                plots.field_map(
                    X, Y, mask, pred, target.split("_")[0], label, arrows, not arrows, survey
                ),
                target,
            )
        )

    targets = list(dict.fromkeys([h["target"] for h in history] + list(diagnoses)))
    if targets:
        parts.append("<h2>Residuals: where the models fail</h2>")
        parts.append(
            "<p>Held-out residuals from spatially blocked 5-fold cross-validation of the latest fit of each "
            "target (measured minus predicted).</p>"
        )
    for target in targets:
        try:
            terms = _latest_terms(history, target)
            note(f"report: residuals of {target} ...", progress)
            sm = SurveyModel(survey, target, terms).fit()
            cv = sm.cv(blocked_folds(survey.xy)[0])
        except WorkbenchError as exc:
            parts.append(f"<p class=small>{html.escape(target)}: {html.escape(str(exc))}</p>")
            continue
        unit = " deg" if sm.circular else ""
        parts.append(f"<h3>{html.escape(target)}: {html.escape(' + '.join(terms))}</h3>")
        parts.append(
            f"<p>CV RMSE {cv.rmse:.4g}{unit}, MAE {cv.mae:.4g}{unit}, 95 % coverage {cv.coverage95:.1%}.</p><ul>"
        )
        parts += [f"<li>{html.escape(s)}</li>" for s in failure_summary(survey, cv.error, unit)]
        parts.append("</ul>")
        parts.append(
            _img(
                plots.scatter_map(
                    survey, cv.error, f"{target}: held-out residuals", "residual", "RdBu_r", True
                ),
                "residual map",
            )
        )
        extra = [i for s in sm.term_specs for i in s.inputs if i != "position"]
        parts.append(
            _img(
                plots.residual_panels(
                    survey, cv.error, extra, f"{target}: residual against covariates", target
                ),
                "residual panels",
            )
        )

    parts.append("<h2>Missing effects, ranked</h2>")
    if not diagnoses:
        parts.append(
            f"<p>No diagnosis yet: run <code>forcemap diagnose {html.escape(table.name)} --target TARGET</code>.</p>"
        )
    for target, d in diagnoses.items():
        found = d.get("missing_effect_found")
        base = d["baseline"]
        parts.append(
            f"<h3>{html.escape(target)} (model {html.escape(' + '.join(base['terms']))}, CV RMSE {base['cv_rmse']:.4g})</h3>"
        )
        if found and d["candidates"]:
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
                f"<tr><td>{i}</td><td>{html.escape(c['covariate'])}</td><td>{c['cv_rmse']:.4g}</td>"
                f"<td>{c['improvement']:+.1%}</td><td class=small>{html.escape(c['explanation'])}</td></tr>"
            )
        parts.append("</table>")
    parts += rounds_section(diagnoses)

    parts.append("<h2>Error history</h2>")
    if history:
        parts.append(
            "<table><tr><th>fit</th><th>target</th><th>terms</th><th>CV RMSE</th><th>MAE</th><th>coverage 95 %</th></tr>"
        )
        for h in history:
            parts.append(
                f"<tr><td>{h['fit']}</td><td>{html.escape(h['target'])}</td><td>{html.escape(' + '.join(h['terms']))}</td>"
                f"<td>{h['cv_rmse']:.4g}</td><td>{h['cv_mae']:.4g}</td><td>{h['coverage95']:.1%}</td></tr>"
            )
        parts.append("</table>")
        parts.append(_img(plots.history_figure(history), "error history"))
    else:
        parts.append("<p>No fits recorded yet.</p>")
    parts += mission_section(table, survey)  # `forcemap plan`'s newest plan, if any
    body = "\n".join(parts)
    return f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>forcemap report: {html.escape(table.name)}</title><style>{CSS}</style></head><body>\n{body}\n</body></html>\n"
