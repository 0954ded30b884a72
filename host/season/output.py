"""What `forcemap season` writes into SEASON_DIR: season.json (per-survey scales, offsets, wind, the models'
hyperparameters, the staleness pairs and half-life, the depth CV, the rejected logs), maps.npz (the maps
and their standard deviations on a grid in the season's frame), the figures and season.html."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
from forcemap.host.outputs import atomic_path, atomic_write
from forcemap.host.season.levels import rating_check, rating_figure, survey_levels
from forcemap.host.season.run import Season
from forcemap.host.season.staleness import binned
from forcemap.host.workbench.fits.plots import new_figure, png_bytes

FILES = ("season.json", "maps.npz", "season.html")
GRID_NX = 90


def iso(t: float) -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(t))


def grid(season: Season) -> tuple[np.ndarray, np.ndarray]:
    x0, x1, y0, y1 = season.frame.extent
    ny = max(10, min(60, int(GRID_NX * (y1 - y0) / max(x1 - x0, 1e-6))))
    return np.meshgrid(np.linspace(x0, x1, GRID_NX), np.linspace(y0, y1, ny))


def maps(season: Season) -> dict[str, np.ndarray]:
    """The maps on the grid: depth, the current's shape at scale 1 (east, north), each with its std, and the
    wind per survey (K x grid)."""
    X, Y = grid(season)
    Z = np.column_stack([X.ravel(), Y.ravel()])
    out = {"x": X, "y": Y}
    Phi = season.frame.space_features(Z)
    if season.depth is not None:
        mu, sd = season.depth.post.predict(Phi)
        out["depth"], out["depth_sd"] = mu[:, 0].reshape(X.shape), sd.reshape(X.shape)
    if season.current is not None:
        mu, sd = season.current.post.predict(Phi)
        for j, c in enumerate(("east", "north")):
            out[f"current_{c}"] = mu[:, j].reshape(X.shape)
            out[f"current_{c}_sd"] = sd.reshape(X.shape)
    Pw = season.frame.wind_features(Z)
    winds = [w[0].predict(Pw, False)[0] if w else np.full((len(Z), 2), np.nan) for w in season.wind]
    out["wind_east"] = np.array([w[:, 0].reshape(X.shape) for w in winds])
    out["wind_north"] = np.array([w[:, 1].reshape(X.shape) for w in winds])
    return out


def summary(season: Season, m: dict[str, np.ndarray]) -> dict:
    cur = season.current
    cur_paths = [s.path for s in season.surveys if s.has["current_east"] and s.has["current_north"]]
    scale = dict(zip(cur_paths, cur.scales.tolist(), strict=True)) if cur else {}
    offset = dict(zip(cur_paths, cur.offsets.tolist(), strict=True)) if cur else {}
    levels = survey_levels(season)
    surveys = []
    for k, s in enumerate(season.surveys):
        we, wn = np.nanmean(m["wind_east"][k]), np.nanmean(m["wind_north"][k])
        surveys.append(
            {
                "path": s.path,
                "start": iso(s.t0),
                "t0": s.t0,
                "t1": s.t1,
                "samples": s.n,
                "current_scale": scale.get(s.path),
                "current_offset_mps": offset.get(s.path),
                "water_level_m": levels[s.path][0] if s.path in levels else None,
                "water_level_sd_m": levels[s.path][1] if s.path in levels else None,
                "wind_mean_speed_mps": None if math.isnan(we) else float(math.hypot(we, wn)),
                "wind_mean_from_deg": None
                if math.isnan(we)
                else float((math.degrees(math.atan2(-we, -wn))) % 360.0),
                "measured": [k2 for k2, v in s.has.items() if v],
                "notes": s.notes,
            }
        )
    out = {
        "frame": {
            "lat0": season.frame.lat0,
            "lon0": season.frame.lon0,
            "extent_m": season.frame.extent,
        },
        "basis": {"space": len(season.frame.space.J) + 1, "wind": len(season.frame.wind.J) + 1},
        "runner": season.runner,
        "timings_s": season.timings,
        "samples": int(sum(s.n for s in season.surveys)),
        "surveys": surveys,
        "rejected": [{"path": r.path, "reason": r.reason} for r in season.rejected],
    }
    if season.depth is not None:
        d = season.depth
        out["depth"] = {
            "theta": d.theta.tolist(),
            "y_scale": d.y_scale,
            "log_evidence": d.log_evidence,
            "with_levels": d.levels is not None,
            "levels_evidence_gain": d.levels_evidence_gain,
            "datum": depth_datum(season),
        }
        check = rating_check(season)
        if check is not None:
            out["rating"] = check
    if cur is not None:
        out["current"] = {
            "theta": cur.theta.tolist(),
            "y_scale": cur.y_scale,
            "with_offsets": cur.with_offsets,
            "offsets_evidence_gain": cur.evidence_gain,
            "rounds": cur.rounds,
        }
    if season.stale is not None:
        out["staleness"] = season.stale.to_json()
    if season.cv:
        out["depth_cv"] = season.cv
    return out


def depth_datum(season: Season) -> str:
    """What the season's depth map is measured from."""
    if season.frame.gauge is not None:
        return f"depth below {season.frame.gauge.datum} ({season.frame.gauge.layout})"
    if season.depth is not None and season.depth.levels is not None:
        return "depth below the surface at the season's mean level (one level per survey, fitted)"
    return "depth below the water surface at the time of each sounding (not reduced to a datum)"


def figures(season: Season, m: dict[str, np.ndarray]) -> dict[str, bytes]:
    figs: dict[str, bytes] = {}
    check = rating_check(season)
    if check is not None:
        figs["rating.png"] = png_bytes(rating_figure(check))
    cur = season.current
    if cur is not None:
        fig = new_figure((8, 3.2))
        ax = fig.add_subplot(111)
        t = [iso(s.t0)[:10] for s in season.surveys if s.has["current_east"]]
        days = np.array([s.t0 for s in season.surveys if s.has["current_east"]])
        ax.plot((days - days.min()) / 86400.0, cur.scales, "o-")
        ax.set_xlabel(f"days since {t[0]}")
        ax.set_ylabel("current scale (1 = season mean)")
        ax.set_title("per-survey current scale (discharge)")
        figs["scales.png"] = png_bytes(fig)
    for key, title in (
        ("depth", "static depth (m)"),
        ("current_east", "current shape, east (m/s)"),
    ):
        if key not in m:
            continue
        fig = new_figure((9, 5))
        for i, (name, what) in enumerate(((key, title), (key + "_sd", "its std"))):
            ax = fig.add_subplot(2, 1, i + 1)
            pc = ax.pcolormesh(m["x"], m["y"], m[name], shading="auto")
            if key == "current_east" and i == 0:
                q = (slice(None, None, 6), slice(None, None, 6))
                ax.quiver(m["x"][q], m["y"][q], m["current_east"][q], m["current_north"][q])
            fig.colorbar(pc, ax=ax)
            ax.set_title(what)
            ax.set_aspect("equal")
        figs[f"{key.split('_')[0]}.png"] = png_bytes(fig)
    st = season.stale
    if st is not None:
        fig = new_figure((10, 3.5))
        for i, (x, label) in enumerate(
            ((st.age_days, "map age (days)"), (st.dscale, "|change in scale|"))
        ):
            ax = fig.add_subplot(1, 2, i + 1)
            ax.plot(x, st.rmse, ".", alpha=0.4)
            bx, by = binned(x, st.rmse)
            ax.plot(bx, by, "r-", lw=2)
            ax.set_xlabel(label)
            ax.set_ylabel("current RMSE of the old map (m/s)")
        figs["staleness.png"] = png_bytes(fig)
    return figs


def write(season: Season, out: Path) -> list[Path]:
    from forcemap.host.report.season_section import season_page

    m = maps(season)
    data = summary(season, m)
    figs = figures(season, m)
    written = []
    with atomic_write(out / "season.json") as f:
        json.dump(data, f, indent=1)
        f.write("\n")
    written.append(out / "season.json")
    with atomic_path(out / "maps.npz") as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **m)
    written.append(out / "maps.npz")
    for name, png in figs.items():
        with atomic_write(out / name, "wb") as f:
            f.write(png)
        written.append(out / name)
    with atomic_write(out / "season.html") as f:
        f.write(season_page(data, figs))
    written.append(out / "season.html")
    return written
