"""The live maps as Foxglove messages: `/map/<target>` grids (foxglove.Grid), `/map/info`, and GeoJSON
layers for the Map panel: current and wind arrows, depth contours, and the samples coloured by value."""

from __future__ import annotations

import base64
import json
import math
from typing import Any

import numpy as np
from forcemap.host.contours import contour_lines
from forcemap.host.live.growing import MapGrid
from forcemap.host.log.live_messages import MapInfo
from forcemap.host.log.record import FLOAT32, GeoJSON, Grid, Time
from forcemap.host.vessel.geodesy import LocalFrame

ARROWS = 12  # along the longer side
SAMPLES_SHOWN = 2000
FRAME = "survey"  # the survey's local frame: x east, y north of /map/info's lat0, lon0 (metres)
COLOURS = ("#2c7bb6", "#abd9e9", "#ffffbf", "#fdae61", "#d7191c")  # low to high


def to_lonlat(
    x: np.ndarray, y: np.ndarray, lat0: float, lon0: float
) -> tuple[np.ndarray, np.ndarray]:
    """(lon, lat) of local (x, y) in the survey's frame (GeoJSON's order)."""
    lat, lon = LocalFrame(lat0, lon0).to_latlon(x, y)
    return lon, lat


def colour(value: float, lo: float, hi: float) -> str:
    if not math.isfinite(value) or hi <= lo:
        return COLOURS[len(COLOURS) // 2]
    k = int(np.clip((value - lo) / (hi - lo) * len(COLOURS), 0, len(COLOURS) - 1))
    return COLOURS[k]


def _stamp(t_s: float) -> Time:
    ns = int(round(t_s * 1e9))
    return Time(ns // 1_000_000_000, ns % 1_000_000_000)


def grid_message(g: MapGrid) -> Grid:
    """All of the map's fields as float32 cells, row-major from (x0, y0)."""
    names = sorted(g.fields)
    ny, nx = g.shape
    cells = np.stack([g.fields[k].astype("<f4") for k in names], axis=-1)  # (ny, nx, k)
    return Grid(
        _stamp(g.t_fit),
        FRAME,
        {"position": {"x": g.x0, "y": g.y0, "z": 0.0},
         "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
        nx,
        {"x": g.step, "y": g.step},
        nx * 4 * len(names),
        4 * len(names),
        [{"name": k, "offset": 4 * i, "type": FLOAT32} for i, k in enumerate(names)],
        base64.b64encode(cells.tobytes()).decode("ascii"),
    )  # fmt: skip


def info_message(g: MapGrid) -> MapInfo:
    v, sd = g.fields[g.value_field], g.fields[g.sd_field]
    ny, nx = g.shape
    return MapInfo(
        g.target, g.t_fit, g.lat0, g.lon0, g.x0, g.y0, g.step, nx, ny, g.n_samples, 0.0,
        g.hyper_age_s, sorted(g.fields), g.n_hyper, g.basis_covers, float(np.nanmin(v)),
        float(np.nanmax(v)), float(np.nanmax(sd)), g.reason,
    )  # fmt: skip


def _feature(geometry: dict[str, Any], props: dict[str, Any]) -> dict[str, Any]:
    return {"type": "Feature", "geometry": geometry, "properties": props}


def arrows(g: MapGrid) -> dict[str, Any]:
    """An arrow per few cells, pointing where the air or water moves, coloured by its uncertainty."""
    ny, nx = g.shape
    every = max(1, max(nx, ny) // ARROWS)
    e, n, sd = g.fields["east"], g.fields["north"], g.fields["speed_sd"]
    vmax = float(np.nanmax(np.hypot(e, n))) or 1.0
    length = every * g.step * 0.9 / vmax  # metres per m/s: the fastest arrow spans its cell
    feats = []
    sd_hi = float(np.nanmax(sd))
    for j in range(every // 2, ny, every):
        for i in range(every // 2, nx, every):
            x, y = g.x0 + i * g.step, g.y0 + j * g.step
            dx, dy = e[j, i] * length, n[j, i] * length
            head = [(x + dx - 0.3 * (dx * c - dy * s), y + dy - 0.3 * (dx * s + dy * c))
                    for c, s in ((math.cos(0.5), math.sin(0.5)), (math.cos(-0.5), math.sin(-0.5)))]  # fmt: skip
            xs = np.array([head[0][0], x + dx, x, x + dx, head[1][0]])
            ys = np.array([head[0][1], y + dy, y, y + dy, head[1][1]])
            lon, lat = to_lonlat(xs, ys, g.lat0, g.lon0)
            speed = float(math.hypot(e[j, i], n[j, i]))
            feats.append(_feature(
                {"type": "LineString", "coordinates": np.column_stack([lon, lat]).round(7).tolist()},
                {"name": f"{g.target} {speed:.2f} m/s ± {sd[j, i]:.2f}",
                 "style": {"color": colour(sd[j, i], 0.0, sd_hi), "weight": 2}},
            ))  # fmt: skip
    return {"type": "FeatureCollection", "features": feats}


def contours(g: MapGrid, levels: int = 8) -> dict[str, Any]:
    """Depth contours (m) at round levels."""
    d = g.fields["depth"]
    ny, nx = d.shape
    lo, hi = float(np.nanmin(d)), float(np.nanmax(d))
    feats = []
    for level, lines in contour_lines(
        g.x0 + g.step * np.arange(nx), g.y0 + g.step * np.arange(ny), d, levels
    ):
        for line in lines:
            lon, lat = to_lonlat(line[:, 0], line[:, 1], g.lat0, g.lon0)
            feats.append(_feature(
                {"type": "LineString", "coordinates": np.column_stack([lon, lat]).round(7).tolist()},
                {"name": f"{level:g} m", "style": {"color": colour(level, lo, hi), "weight": 1}},
            ))  # fmt: skip
    return {"type": "FeatureCollection", "features": feats}


def samples_layer(rows: dict[str, list[float]]) -> dict[str, Any]:
    """The latest samples as points coloured by the current's speed (depth and wind in their names)."""
    lat, lon = rows["lat"][-SAMPLES_SHOWN:], rows["lon"][-SAMPLES_SHOWN:]
    ce, cn = rows["current_east"][-SAMPLES_SHOWN:], rows["current_north"][-SAMPLES_SHOWN:]
    depth = rows["depth"][-SAMPLES_SHOWN:]
    speed = np.hypot(ce, cn)
    ok = np.isfinite(speed)
    lo, hi = (float(np.min(speed[ok])), float(np.max(speed[ok]))) if ok.any() else (0.0, 1.0)
    feats = []
    for k in range(len(lat)):
        name = f"current {speed[k]:.2f} m/s, depth {depth[k]:.1f} m"
        feats.append(_feature(
            {"type": "Point", "coordinates": [round(lon[k], 7), round(lat[k], 7)]},
            {"name": name, "style": {"color": colour(float(speed[k]), lo, hi), "radius": 3}},
        ))  # fmt: skip
    return {"type": "FeatureCollection", "features": feats}


def map_messages(grids: list[MapGrid], maps: Any) -> list[tuple[str, Any]]:
    """(topic, record) of every message an update publishes."""
    out: list[tuple[str, Any]] = []
    for g in grids:
        out.append((f"/map/{g.target}", grid_message(g)))
        out.append(("/map/info", info_message(g)))
        layer = contours(g) if g.target == "depth" else arrows(g)
        out.append((f"/map/layers/{g.target}", GeoJSON(json.dumps(layer, separators=(",", ":")))))
    if grids:
        doc = samples_layer(maps.rows)
        out.append(("/map/layers/samples", GeoJSON(json.dumps(doc, separators=(",", ":")))))
    return out
