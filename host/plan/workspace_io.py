"""The latest plan of a survey, kept in its workspace (`TABLE.forcemap/plans/`) for the report."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from forcemap.host.outputs import atomic_write
from forcemap.host.workbench.fits.workspace import workspace_dir

from .metrics import missed_stretches

PLANS = "plans"
EVERY = 5  # keep one predicted track point a second (the prediction steps at 0.2 s)


def _track(track) -> dict:  # type: ignore[no-untyped-def]
    return {"x": track.x[::EVERY].round(2).tolist(), "y": track.y[::EVERY].round(2).tolist()}


def save_plan(table: Path, name: str, result, maps) -> Path:  # type: ignore[no-untyped-def]
    """Write plans/NAME.json: lines, both missions' waypoints and predicted tracks (survey frame, m)."""
    folder = workspace_dir(table) / PLANS
    folder.mkdir(exist_ok=True)
    o, p = result.original, result.planned
    doc = {
        "name": name,
        "lines": p.plan.lines.round(3).tolist(),
        "original": {"wps": o.plan.wps.round(3).tolist(), "track": _track(o.track)},
        "planned": {"wps": p.plan.wps.round(3).tolist(), "track": _track(p.track)},
        "result": result.to_json(),
        "original_misses_m": missed_stretches(o.track.xy, p.plan.lines),
        "planned_misses_m": missed_stretches(p.track.xy, p.plan.lines),
        "notes": maps.notes,
    }
    path = folder / f"{name}.json"
    with atomic_write(path) as f:
        f.write(
            json.dumps(doc, default=lambda v: v.item() if isinstance(v, np.generic) else str(v))
        )
    return path


def load_plans(table: Path) -> list[dict]:
    """Every saved plan of the survey, newest first."""
    folder = workspace_dir(table, create=False) / PLANS
    if not folder.is_dir():
        return []
    paths = sorted(folder.glob("*.json"), key=lambda p: p.stat().st_mtime, reverse=True)
    out = []
    for p in paths:
        try:
            out.append(json.loads(p.read_text()))
        except json.JSONDecodeError:
            continue
    return out
