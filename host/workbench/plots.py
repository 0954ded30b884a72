"""Figures: residual maps and panels, model maps with arrows and contours, error history.

Each figure is a matplotlib `Figure` on its own Agg canvas: nothing here touches pyplot's global state or
the process's backend.
"""

from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from forcemap.host.workbench.table import NOT_COVARIATES, Survey, family, is_circular
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.spatial import cKDTree

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


def map_grid(survey: Survey, nx: int = 70) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A regular grid over the track, and a mask of the cells near enough to a sample to be mapped."""
    xy = survey.xy
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    span = hi - lo
    ny = max(10, int(nx * span[1] / max(span[0], 1e-6)))
    gx, gy = np.linspace(lo[0], hi[0], nx), np.linspace(lo[1], hi[1], min(ny, 120))
    X, Y = np.meshgrid(gx, gy)
    dist, _ = cKDTree(xy).query(np.column_stack([X.ravel(), Y.ravel()]))
    mask = (dist <= max(10.0, 0.08 * float(span.max()))).reshape(X.shape)
    return X, Y, mask


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
        ax.set_xlabel("t (min)" if name == "t" else name, fontsize=9)
        ax.set_ylabel("residual", fontsize=9)
    for ax in axes.ravel()[len(names) :]:
        ax.axis("off")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def field_map(
    X, Y, mask, pred: dict, title: str, label: str, arrows: bool, contours: bool, survey: Survey
):
    """Model mean (colour; arrows for a vector field, contours for a scalar) and its uncertainty, side by side."""
    fig = new_figure((9, 7.5))
    a1, a2 = fig.subplots(2, 1)
    shape = X.shape
    key = "speed" if arrows and "speed" in pred else "mean"
    mean = np.where(mask, pred[key].reshape(shape), np.nan)
    std = np.where(mask, pred["speed_std" if key == "speed" else "std"].reshape(shape), np.nan)
    lo, hi = np.nanpercentile(mean, [1, 99]) if np.isfinite(mean).any() else (0.0, 1.0)
    pc = a1.pcolormesh(X, Y, mean, shading="auto", cmap="viridis", vmin=lo, vmax=hi)
    fig.colorbar(pc, ax=a1, label=label, shrink=0.85)
    if arrows and "east" in pred:
        step = max(1, shape[1] // 25)
        E = np.where(mask, pred["east"].reshape(shape), np.nan)
        N = np.where(mask, pred["north"].reshape(shape), np.nan)
        a1.quiver(
            X[::step, ::step],
            Y[::step, ::step],
            E[::step, ::step],
            N[::step, ::step],
            color="white",
            scale_units="xy",
            angles="xy",
        )
    if contours:
        cs = a1.contour(X, Y, mean, levels=np.linspace(lo, hi, 8), colors="k", linewidths=0.6)
        a1.clabel(cs, fontsize=7, fmt="%.1f")
    a1.plot(survey.xy[:, 0], survey.xy[:, 1], ",", color="0.6", alpha=0.3)
    _axes_map(a1, f"{title}: model mean")
    top = np.nanpercentile(std, 99) if np.isfinite(std).any() else 1.0
    pc2 = a2.pcolormesh(X, Y, std, shading="auto", cmap="magma", vmin=0.0, vmax=top)
    fig.colorbar(pc2, ax=a2, label=f"std of {label}", shrink=0.85)
    _axes_map(a2, f"{title}: model uncertainty (1 std)")
    fig.tight_layout()
    return fig


def history_figure(history: list[dict]):
    """CV RMSE of every fit, one line per target, labelled with the terms added."""
    fig = new_figure((9, 3.8))
    ax = fig.subplots()
    targets = list(dict.fromkeys(h["target"] for h in history))
    for target in targets:
        rows = [h for h in history if h["target"] == target]
        rmse0 = rows[0]["cv_rmse"] or 1.0
        ax.plot([h["fit"] for h in rows], [h["cv_rmse"] / rmse0 for h in rows], "o-", label=target)
        for h in rows:
            extra = [t for t in h["terms"] if t not in ("const", "gp(position, matern32)")]
            ax.annotate(
                "+" + ", ".join(extra) if extra else "baseline",
                (h["fit"], h["cv_rmse"] / rmse0),
                fontsize=7,
                xytext=(3, 3),
                textcoords="offset points",
            )
    ax.set_xlabel("fit number")
    ax.set_ylabel("CV RMSE / first fit's")
    ax.set_title("error history: CV RMSE as effects are added", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
