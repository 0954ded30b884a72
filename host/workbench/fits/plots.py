"""Figures: residual maps and panels, error history (the model maps: `host.report.map_figure`).

Each figure is a matplotlib `Figure` on its own Agg canvas: nothing here touches pyplot's global state or
the process's backend.
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from forcemap.host.workbench.survey.table import (
    NOT_COVARIATES,
    Survey,
    family,
    is_circular,
    unit_of,
)
from forcemap.host.workbench.terms.spec import BASELINE
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

PANEL_COVARIATES = (
    "t",
    "heading",
    "sog",
    "depth",
    "yaw_rate",
    "cog",
    "crab",
    "wind_dir",
    "wind_speed",
    "water_temp",
    "throttle",
)


def new_figure(figsize: tuple[float, float]) -> Figure:
    """A figure drawn by its own Agg canvas."""
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


def png_bytes(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return buf.getvalue()


def save(fig, path: Path) -> Path:
    path.write_bytes(png_bytes(fig))
    return path


def _axes_map(ax, title: str) -> None:
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_title(title, fontsize=10)


def scatter_map(
    survey: Survey,
    values: np.ndarray,
    title: str,
    label: str,
    cmap: str = "viridis",
    symmetric=False,
):
    fig = new_figure((8, 3.6))
    ax = fig.subplots()
    xy = survey.xy
    kw = {}
    if symmetric:
        lim = float(np.nanpercentile(np.abs(values), 98)) or 1.0
        kw = {"vmin": -lim, "vmax": lim}
    sc = ax.scatter(xy[:, 0], xy[:, 1], c=values, s=3, cmap=cmap, **kw)
    fig.colorbar(sc, ax=ax, label=label, shrink=0.85)
    _axes_map(ax, title)
    return fig


def residual_panels(
    survey: Survey,
    resid: np.ndarray,
    extra: Mapping[str, np.ndarray] | None = None,
    title: str = "",
    target: str = "",
):
    """Residual against time, heading, boat speed, depth, the model's covariates `extra` (name -> values at
    the samples, derived ones included) and every other column, with binned medians (never against the
    target's own family: a residual always correlates with the reading it came from)."""
    extra = dict(extra or {})
    own = family(target)
    names = [
        n
        for n in PANEL_COVARIATES
        if (n == "t" or n in survey.columns) and (own is None or family(n) != own)
    ]
    others = [n for n in survey.numeric_columns() if own is None or family(n) != own]
    for n in list(extra) + others:
        if n not in names and (n in extra or n in survey.columns) and n not in NOT_COVARIATES:
            names.append(n)
    names = names[:21]
    cols = 3
    rows = int(np.ceil(len(names) / cols))
    fig = new_figure((11, 2.6 * rows))
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax, name in zip(axes.ravel(), names, strict=False):
        if name == "t":
            x = survey.trel / 60.0
        else:
            x = survey.columns[name] if name in survey.columns else extra[name]
        ok = np.isfinite(x)
        ax.scatter(x[ok], resid[ok], s=1, alpha=0.3, color="tab:blue")
        edges = (
            np.linspace(0, 360, 19)
            if is_circular(name)
            else np.quantile(x[ok], np.linspace(0, 1, 16))
        )
        idx = np.clip(np.digitize(x[ok], edges) - 1, 0, len(edges) - 2)
        med = [
            np.median(resid[ok][idx == i]) if (idx == i).sum() > 5 else np.nan
            for i in range(len(edges) - 1)
        ]
        ax.plot(0.5 * (edges[1:] + edges[:-1]), med, color="tab:red", lw=2)
        ax.axhline(0, color="k", lw=0.5)
        u = unit_of(name)
        ax.set_xlabel("t (min)" if name == "t" else (f"{name} ({u})" if u else name), fontsize=9)
        ax.set_ylabel(f"residual ({tu})" if (tu := unit_of(target)) else "residual", fontsize=9)
    for ax in axes.ravel()[len(names) :]:
        ax.axis("off")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def history_figure(history: list[dict]):
    """CV RMSE of every fit as a separate point at its fit number (the order the fits were made; no line:
    fits are not a series in between), one colour per target, labelled with the terms added."""
    from matplotlib.ticker import MaxNLocator

    fig = new_figure((9, 3.8))
    ax = fig.subplots()
    targets = list(dict.fromkeys(h["target"] for h in history))
    for target in targets:
        rows = [h for h in history if h["target"] == target]
        rmse0 = rows[0]["cv_rmse"] or 1.0
        ax.plot(
            [h["fit"] for h in rows],
            [h["cv_rmse"] / rmse0 for h in rows],
            "o",
            ls="none",
            label=target,
        )
        for h in rows:
            extra = [t for t in h["terms"] if t not in BASELINE]
            ax.annotate(
                "+" + ", ".join(extra) if extra else "baseline",
                (h["fit"], h["cv_rmse"] / rmse0),
                fontsize=7,
                xytext=(3, 3),
                textcoords="offset points",
            )
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    fits = [h["fit"] for h in history]
    ax.set_xlim(min(fits) - 0.5, max(fits) + 0.5)
    ax.set_xlabel("fit number (in the order made)")
    ax.set_ylabel("CV RMSE / the target's first fit's (ratio, 1 = unchanged)")
    ax.set_title("error history: CV RMSE as effects are added", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
