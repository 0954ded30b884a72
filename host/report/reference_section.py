"""The report's tide on a reference current: each place's ratio and time offset to its station, and the
current at hours of the tide (the local atlas), from the latest fit of the current (docs/REFERENCE.md)."""

from __future__ import annotations

import html
import math
from dataclasses import replace

import numpy as np
from forcemap.host.gis.grid import evaluate, true_north
from forcemap.host.report.map_figure import decorate, figsize, img
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.fits.fit import map_terms
from forcemap.host.workbench.survey import reference
from forcemap.host.workbench.targets.survey_fits import mid_time
from forcemap.host.workbench.terms.time_terms import iso, reference_lines

# the atlas: the current at these hours from the reference station's strongest flood nearest mid-survey
ATLAS_HOURS = (-6, -3, 0, 3, 6)


def strongest_flood(survey, near: float) -> tuple[str, float]:
    """The survey's most used station and the time of its strongest flood within 7 h of `near`."""
    st = reference.stations_used(survey)[0]
    t = near + np.arange(-7 * 3600.0, 7 * 3600.0 + 1.0, 120.0)
    return st.id, float(t[int(np.argmax(st.speed(t)))])


def _panels(grid, n: int):  # type: ignore[no-untyped-def]
    from forcemap.host.workbench.fits.plots import new_figure

    (w, h), side = figsize(grid)
    fig = new_figure((w * n / 2, h) if side else (w, h * n / 2))
    fig.set_layout_engine("constrained")
    axes = fig.subplots(1, n) if side else fig.subplots(n, 1)
    sx, sy = grid.x0, grid.y1 - grid.ny * grid.resolution
    X, Y = np.meshgrid(grid.easting - sx, grid.northing - sy)
    return fig, np.atleast_1d(axes), X, Y, (sx, sy)


def relation_figure(grid, layer, track):  # type: ignore[no-untyped-def]
    """The flood's ratio and time offset (min) to the station."""
    fig, axes, X, Y, (sx, sy) = _panels(grid, 2)
    for ax, band, label, cmap in ((axes[0], "ratio", "ratio to the station", "viridis"),
                                  (axes[1], "offset", "later than the station (min)", "coolwarm")):  # fmt: skip
        v = layer.bands[band] / (60.0 if band == "offset" else 1.0)
        lo, hi = np.nanpercentile(v, [2, 98]) if np.isfinite(v).any() else (0.0, 1.0)
        pc = ax.pcolormesh(X, Y, v, shading="auto", cmap=cmap, vmin=lo, vmax=hi)
        fig.colorbar(pc, ax=ax, label=label)
        ax.plot(track[0] - sx, track[1] - sy, ",", color="0.6", alpha=0.3)
        ax.set_title(f"flood: {label}", fontsize=10)
        decorate(ax, grid, true_north(grid))
    return fig


def atlas_figure(grid, layers, hours, track):  # type: ignore[no-untyped-def]
    """The current's speed (colour) and velocity (arrows) at each hour of the tide, on one colour scale."""
    fig, axes, X, Y, (sx, sy) = _panels(grid, len(layers))
    top = max(float(np.nanmax(lay.bands["speed"])) if np.isfinite(lay.bands["speed"]).any() else 0.1
              for lay in layers)  # fmt: skip
    north = true_north(grid)
    c, s = math.cos(math.radians(north)), math.sin(math.radians(north))
    step = max(1, max(grid.nx, grid.ny) // 15)
    sl = (slice(None, None, step), slice(None, None, step))
    for ax, lay, h in zip(axes, layers, hours, strict=True):
        pc = ax.pcolormesh(X, Y, lay.bands["speed"], shading="auto", cmap="viridis", vmin=0, vmax=top)
        e, n = lay.bands["east"], lay.bands["north"]
        u, v = e * c + n * s, -e * s + n * c
        ax.quiver(X[sl], Y[sl], u[sl], v[sl], color="white", angles="xy", scale_units="xy",
                  scale=max(top, 1e-9) / (0.9 * step * grid.resolution))  # fmt: skip
        ax.plot(track[0] - sx, track[1] - sy, ",", color="0.6", alpha=0.2)
        ax.set_title(f"strongest flood {h:+d} h", fontsize=9)
        decorate(ax, grid, north)
    fig.colorbar(pc, ax=list(axes), label="current speed (m/s)")
    return fig


def reference_section(ctx) -> list[str]:  # type: ignore[no-untyped-def]
    """The relation and the atlas, where the latest current fit is on a reference current."""
    survey = ctx.survey
    if survey.reference is None or survey.vector_target("current_speed") is None:
        return []
    try:
        sm = ctx.model("current_speed", map_terms(survey, ctx.history, "current_speed"))
    except WorkbenchError:
        return []
    if getattr(sm, "relation", None) is None:
        return []
    grid, track, _ = ctx.frame
    layer = evaluate(grid, sm)
    sid, flood = strongest_flood(sm.survey, mid_time(sm.survey))
    at = [flood + h * 3600.0 for h in ATLAS_HOURS]
    layers = [evaluate(replace(grid, at=t, layers={}), sm) for t in at]
    parts = ["<h2>The tide on the reference current</h2>"]
    parts += [f"<p>{html.escape(line.strip())}</p>" for line in reference_lines(sm)]
    parts.append(img(relation_figure(grid, layer, track), "ratio and offset", "map"))
    parts.append(
        f"<p>The local atlas: the current at hours from {html.escape(sid)}'s strongest flood nearest the "
        f"survey's middle ({html.escape(iso(flood))}); any other time with <code>forcemap grid --at</code>.</p>"
    )
    parts.append(img(atlas_figure(grid, layers, ATLAS_HOURS, track), "the local atlas", "map"))
    return parts
