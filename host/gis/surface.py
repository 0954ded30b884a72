"""A depth layer's surface bands: the hypothesis most soundings support at each cell, its uncertainty and
the IHO S-44 order it meets (forcemap.host.workbench.depth.surface), beside the GP map's bands; and the GP
map's cells that no kept sounding is near left blank (a lost stretch makes no cell)."""

from __future__ import annotations

import numpy as np
from forcemap.host.workbench.depth import surface as depth_surface

# band -> what it is (host/gis/names.py gives each its CF attributes)
SURFACE_BANDS = (
    "surface", "surface_sd", "surface_tvu", "surface_order", "surface_hypotheses",
    "surface_soundings", "surface_support",
)  # fmt: skip


def surface_bands(grid, survey, soundings: dict | None = None) -> dict[str, np.ndarray]:
    """The surface bands of a depth layer on ``grid``'s mapped cells (NaN elsewhere), from the soundings
    the depth map was fitted on (``soundings``: those its rows' surface accepted,
    forcemap.host.workbench.depth.accepted; else the survey's, as given)."""
    keep = grid.mask.ravel()
    s = depth_surface.survey_soundings(survey) if soundings is None else soundings
    surf = depth_surface.build(grid.local_xy[keep], s, grid.resolution)
    values = {
        "surface": surf.depth,
        "surface_sd": surf.sd,
        "surface_tvu": surf.tvu,
        "surface_order": surf.order(),
        "surface_hypotheses": np.where(surf.soundings > 0, surf.hypotheses, np.nan),
        "surface_soundings": np.where(surf.soundings > 0, surf.soundings, np.nan),
        "surface_support": surf.support,
    }
    out = {}
    for name in SURFACE_BANDS:
        full = np.full(grid.ny * grid.nx, np.nan)
        full[keep] = values[name]
        out[name] = full.reshape(grid.ny, grid.nx)
    return out


def depth_layer(grid, model, layer) -> list[str]:
    """A depth layer's datum and surface bands, from the soundings its model was fitted on (the surface's
    accepted ones, forcemap.host.workbench.depth.accepted), and its note of those the surface rejected:
    the line `fit` prints, figure for figure."""
    from forcemap.host.workbench.depth.water_level import map_datum

    layer.datum = map_datum(model.survey, list(model.terms), grid.at)
    rows = getattr(model, "rows", None)
    layer.bands.update(surface_bands(grid, model.survey, rows.soundings if rows else None))
    spikes = getattr(model, "spikes", None)
    line = spikes.surface_line if spikes is not None else ""
    return [f"{model.target}: {line}"] if line else []


def far_from_soundings(grid, kept_xy: np.ndarray) -> np.ndarray:
    """The grid's cells (flat) farther than its mask distance from every sounding the map was fitted on:
    a cell near only a lost stretch or spikes is not mapped."""
    from scipy.spatial import cKDTree

    if not len(kept_xy):
        return np.ones(grid.ny * grid.nx, bool)
    dist, _ = cKDTree(kept_xy).query(grid.local_xy, distance_upper_bound=grid.max_distance)
    return ~(dist <= grid.max_distance)
