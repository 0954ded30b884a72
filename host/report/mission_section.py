"""The report's mission section: intended, predicted and flown tracks on the map, and where the boat will fail."""

from __future__ import annotations

import base64
import html
from pathlib import Path

import numpy as np
from forcemap.host.plan.metrics import TOL_M
from forcemap.host.plan.workspace_io import load_plans


def _figure(plan: dict, survey):  # type: ignore[no-untyped-def]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(11, 3.4))
    ax.plot(
        survey.columns["x"], survey.columns["y"], color="0.75", lw=0.6, label="flown (this survey)"
    )
    for k, (a, b) in enumerate(np.array(plan["lines"])):
        ax.plot(
            [a[0], b[0]],
            [a[1], b[1]],
            color="k",
            lw=2.2,
            label="intended lines" if k == 0 else None,
        )
    o, p = plan["original"]["track"], plan["planned"]["track"]
    ax.plot(o["x"], o["y"], "--", color="tab:red", lw=1.0, label="original, predicted")
    ax.plot(p["x"], p["y"], color="tab:blue", lw=1.0, label="planned, predicted")
    wps = np.array(plan["planned"]["wps"])
    ax.plot(wps[:, 0], wps[:, 1], ".", color="tab:blue", ms=4, label="planned waypoints")
    _mark_failures(ax, plan)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_title(f"mission {plan['name']}: intended, predicted and flown")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    fig.tight_layout()
    return fig


def _mark_failures(ax, plan: dict) -> None:  # type: ignore[no-untyped-def]
    """Stretches of each line the predicted tracks miss by more than TOL_M, and stretches without headway."""
    styles = (
        ("original_misses_m", "tab:orange", 7, "original misses the line"),
        ("planned_misses_m", "tab:purple", 3, "planned misses the line"),
        ("no_headway_m", "red", 9, "no headway (current >= boat speed)"),
    )
    for key, colour, width, label in styles:
        runs_per_line = plan.get(key) if key != "no_headway_m" else plan["result"]["no_headway_m"]
        first = True
        for (a, b), runs in zip(np.array(plan["lines"]), runs_per_line or [], strict=False):
            length = float(np.hypot(*(b - a)))
            for s, e in runs:
                p0, p1 = a + (b - a) * s / length, a + (b - a) * e / length
                ax.plot([p0[0], p1[0]], [p0[1], p1[1]], color=colour, lw=width, alpha=0.55,
                        solid_capstyle="butt", label=label if first else None)  # fmt: skip
                first = False


def _table(plan: dict) -> str:
    o, p = plan["result"]["original"], plan["result"]["planned"]
    rows = [
        "<table><tr><th>line</th><th>p95 m original / planned</th><th>worst m</th>"
        "<th>coverage</th><th>time on line s</th><th>no headway</th></tr>"
    ]
    for k, (a, b) in enumerate(zip(o["lines"], p["lines"], strict=True)):
        nh = plan["result"]["no_headway_m"][k]
        rows.append(
            f"<tr><td>{k}</td><td>{a['p95']:.1f} / {b['p95']:.1f}</td><td>{a['miss']:.1f} / {b['miss']:.1f}</td>"
            f"<td>{a['coverage']:.0%} / {b['coverage']:.0%}</td><td>{a['time_s']:.0f} / {b['time_s']:.0f}</td>"
            f"<td>{'none' if not nh else ', '.join(f'{s:.0f}-{e:.0f} m' for s, e in nh)}</td></tr>"
        )
    rows.append("</table>")
    return "\n".join(rows)


def read_replans(table: Path) -> list[dict]:
    """The in-flight replanning decisions (/plan/replan) of an MCAP log given as the table."""
    if Path(table).suffix.lower() != ".mcap":
        return []
    from forcemap.host.log.mcap import read_messages

    try:
        return [m.message for m in read_messages([table], "/plan/replan")]
    except Exception:  # a damaged log: the report shows what the rest of it holds
        return []


def replan_section(replans: list[dict]) -> list[str]:
    """One row per in-flight decision: when, after which line, the map, predictions and the reason."""
    from forcemap.host.log.plan_records import describe_counts

    rows = [
        f"<h3>In flight</h3><p>Replanning: {describe_counts(replans)} "
        '(`forcemap run --replan`; docs/PLAN.md, "In flight").</p>',
        "<table><tr><th>after line</th><th>map age s</th><th>current m/s</th>"
        "<th>p95 m kept / new</th><th>coverage kept / new</th><th>uploaded</th><th>reason</th></tr>",
    ]

    def f(v, fmt: str) -> str:  # type: ignore[no-untyped-def]
        return format(v, fmt) if isinstance(v, int | float) else "-"

    for r in replans:
        rows.append(
            f"<tr><td>{int(r.get('line_done', -1)) + 1}</td><td>{f(r.get('map_age_s'), '.0f')}</td>"
            f"<td>{f(r.get('current_mean_mps'), '.2f')}</td>"
            f"<td>{f(r.get('old_p95_m'), '.2f')} / {f(r.get('new_p95_m'), '.2f')}</td>"
            f"<td>{f(r.get('old_coverage'), '.0%')} / {f(r.get('new_coverage'), '.0%')}</td>"
            f"<td>{'yes' if r.get('uploaded') else 'no'}</td><td>{html.escape(str(r.get('reason')))}</td></tr>"
        )
    rows.append("</table>")
    return rows


def mission_section(table: Path, survey) -> list[str]:  # type: ignore[no-untyped-def]
    """HTML parts for the newest plan of this survey (`forcemap plan`) and the in-flight replanning
    decisions logged with it, or nothing if there are neither."""
    plans = load_plans(table)
    replans = read_replans(table)
    if not plans:
        return ["<h2>Mission</h2>", *replan_section(replans)] if replans else []
    from forcemap.host.workbench.fits import plots
    plan = plans[0]
    res = plan["result"]
    png = base64.b64encode(plots.png_bytes(_figure(plan, survey))).decode()
    sens = "; ".join(
        f"{html.escape(k)}: worst-line p95 {v['p95_worst_line']:.2f} m, coverage {v['coverage']:.0%}"
        for k, v in res["sensitivity"].items()
    )
    o, p = res["original"], res["planned"]
    return [
        "<h2>Mission</h2>",
        f"<p>Mission <b>{html.escape(plan['name'])}</b> predicted through this survey's current and wind maps "
        f"(`forcemap plan`). Original: coverage {o['coverage']:.0%} of the intended lines within {TOL_M:.0f} m, "
        f"worst miss {o['miss']:.1f} m, {o['duration_s']:.0f} s. Planned: coverage {p['coverage']:.0%}, worst "
        f"miss {p['miss']:.1f} m, {p['duration_s']:.0f} s"
        f"{' (unchanged: the mission already holds its lines)' if res.get('unchanged') else ''}.</p>",
        f'<img alt="mission tracks" src="data:image/png;base64,{png}">',
        _table(plan),
        f"<p class=small>The map's current is uncertain by {res['current_relative_sd']:.1%} of its speed (1 sd "
        "along the lines: the larger of its predictive sd, what a new measurement would differ by, and its "
        f"blocked-CV RMSE); with the current scaled by twice that: {sens}. A map from another day (other discharge) "
        "can be wrong by far more than that: see docs/PLAN.md.</p>",
        *[f"<p class=small>note: {html.escape(n)}</p>" for n in plan.get("notes", [])],
        *(replan_section(replans) if replans else []),
    ]
