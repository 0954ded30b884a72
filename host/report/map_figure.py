"""The report's model maps: a target's mean and uncertainty on the grid `forcemap grid` writes, with a
scale bar and a true-north arrow, sized to the survey's shape (a long survey gets the page's width)."""

from __future__ import annotations

import base64
import html
import math

import numpy as np
from forcemap.host.gis.grid import POSITIVE, Layer, MapGrid, true_north
from forcemap.host.workbench.fits.plots import new_figure, png_bytes

PAGE_WIDTH_IN = 11.0


def figsize(grid: MapGrid) -> tuple[tuple[float, float], bool]:
    """(width, height) in inches and whether the two panels sit side by side: stacked for a survey wider
    than tall, each panel the page's width; side by side for a tall one."""
    aspect = grid.nx / max(grid.ny, 1)
    if aspect >= 1.0:
        panel_h = min(6.0, max(1.0, (PAGE_WIDTH_IN - 1.8) / aspect))
        return (PAGE_WIDTH_IN, 2 * (panel_h + 0.9)), False
    panel_w = (PAGE_WIDTH_IN - 3.0) / 2
    return (PAGE_WIDTH_IN, min(9.0, max(3.0, panel_w / aspect)) + 0.9), True


def nice_length(span_m: float) -> float:
    """A round scale-bar length near a fifth of the span: 1, 2 or 5 x 10^k m."""
    target = span_m / 5.0
    k = 10 ** math.floor(math.log10(target))
    return max(m * k for m in (1, 2, 5) if m * k <= target)


def decorate(ax, grid: MapGrid, north_deg: float) -> None:
    """Equal axes in metres from the grid's south-west corner, a scale bar, a true-north arrow."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    ax.set_aspect("equal")
    where = f"{grid.zone_name}" + (f", EPSG:{grid.epsg}" if grid.epsg else "")
    ax.set_xlabel(f"m east of {grid.x0:.0f} ({where})", fontsize=8)
    ax.set_ylabel(f"m north of {grid.y1 - grid.ny * grid.resolution:.0f}", fontsize=8)
    ax.tick_params(labelsize=7)
    length = nice_length(grid.nx * grid.resolution)
    label = f"{length / 1000:g} km" if length >= 1000 else f"{length:g} m"
    ax.add_artist(
        AnchoredSizeBar(
            ax.transData, length, label, "lower left", pad=0.4, frameon=True, size_vertical=0
        )
    )
    # true north at the upper right, drawn in points so that it keeps its angle in any axes' shape
    a = math.radians(north_deg)
    head = (0.97, 0.9)
    kw = {"xycoords": "axes fraction", "textcoords": "offset points"}
    ax.annotate(
        "", head, xytext=(-22 * math.sin(a), -22 * math.cos(a)),
        arrowprops={"arrowstyle": "-|>", "color": "k", "lw": 1.5}, **kw,
    )  # fmt: skip
    ax.annotate(
        "N", head, xytext=(-22 * math.sin(a) - 9, -22 * math.cos(a)), ha="center", va="bottom",
        fontsize=9, fontweight="bold", **kw,
    )  # fmt: skip


def point_figure(
    grid: MapGrid,
    track: tuple[np.ndarray, np.ndarray],
    values: np.ndarray,
    title: str,
    label: str,
    cmap: str = "viridis",
    symmetric: bool = False,
):
    """Values at the samples (measurements, residuals) in the model maps' frame and origin, the page's width."""
    aspect = grid.nx / max(grid.ny, 1)
    fig = new_figure((PAGE_WIDTH_IN, min(9.0, max(2.6, (PAGE_WIDTH_IN - 1.8) / aspect + 0.9))))
    fig.set_layout_engine("constrained")
    ax = fig.subplots()
    sx, sy = grid.x0, grid.y1 - grid.ny * grid.resolution
    kw = {}
    if symmetric:
        lim = float(np.nanpercentile(np.abs(values), 98)) or 1.0
        kw = {"vmin": -lim, "vmax": lim}
    sc = ax.scatter(track[0] - sx, track[1] - sy, c=values, s=3, cmap=cmap, **kw)
    fig.colorbar(sc, ax=ax, label=label, shrink=0.85)
    ax.set_xlim(0, grid.nx * grid.resolution)
    ax.set_ylim(0, grid.ny * grid.resolution)
    ax.set_title(title, fontsize=10)
    decorate(ax, grid, true_north(grid))
    return fig


def grid_figure(grid: MapGrid, layer: Layer, track: tuple[np.ndarray, np.ndarray], label: str):
    """Mean (colour; arrows for a vector, contours for a scalar) and predictive 1-sd uncertainty of one layer."""
    (w, h), side = figsize(grid)
    fig = new_figure((w, h))
    fig.set_layout_engine("constrained")
    a1, a2 = fig.subplots(1, 2) if side else fig.subplots(2, 1)
    sx, sy = grid.x0, grid.y1 - grid.ny * grid.resolution
    X, Y = np.meshgrid(grid.easting - sx, grid.northing - sy)
    vector = layer.vector is not None
    mean = layer.bands["speed" if vector else "mean"]
    sd = layer.bands["speed_sd" if vector else "sd"]
    finite = np.isfinite(mean)
    lo, hi = np.nanpercentile(mean, [1, 99]) if finite.any() else (0.0, 1.0)
    pc = a1.pcolormesh(X, Y, mean, shading="auto", cmap="viridis", vmin=lo, vmax=hi)
    fig.colorbar(pc, ax=a1, label=label)
    north = true_north(grid)
    if vector:
        # true east/north components turned into the grid's axes (they differ by the meridian convergence)
        c, s = math.cos(math.radians(north)), math.sin(math.radians(north))
        e, n = layer.bands["east"], layer.bands["north"]
        u, v = e * c + n * s, -e * s + n * c
        step = max(1, max(grid.nx, grid.ny) // 25)
        sl = (slice(None, None, step), slice(None, None, step))
        top = float(np.nanmax(np.hypot(u, v))) if finite.any() else 1.0
        # the fastest arrow spans 0.9 of the spacing between arrows
        scale = max(top, 1e-9) / (0.9 * step * grid.resolution)
        a1.quiver(
            X[sl], Y[sl], u[sl], v[sl], color="white", angles="xy", scale_units="xy", scale=scale
        )
    elif finite.any() and hi > lo and min(mean.shape) >= 2:  # a one-row grid has no contours
        levels = np.linspace(lo, hi, 8)
        if layer.target in POSITIVE:
            levels = levels[levels > 0.0]  # never a depth at or above the surface
        if len(levels):
            cs = a1.contour(X, Y, mean, levels=levels, colors="k", linewidths=0.6)
            a1.clabel(cs, fontsize=7, fmt="%.1f")
    a1.plot(track[0] - sx, track[1] - sy, ",", color="0.6", alpha=0.3)
    a1.set_title(f"{label}: model mean", fontsize=10)
    top = np.nanpercentile(sd, 99) if np.isfinite(sd).any() else 1.0
    pc2 = a2.pcolormesh(X, Y, sd, shading="auto", cmap="magma", vmin=0.0, vmax=top)
    fig.colorbar(pc2, ax=a2, label=f"predictive sd of {label}")
    a2.set_title(
        f"{label}: predictive uncertainty (1 sd of a new measurement, latent + noise)", fontsize=10
    )
    for ax in (a1, a2):
        decorate(ax, grid, north)
    return fig


def img(fig, alt: str, cls: str = "") -> str:
    """An <img> with the figure embedded as base64 PNG (`cls` "map": the page's width)."""
    data = base64.b64encode(png_bytes(fig)).decode()
    klass = f' class="{cls}"' if cls else ""
    return f'<img{klass} alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'
