"""Missions: waypoint lists or generated lawnmower patterns parallel or perpendicular to the flow."""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .geo import Geo
from .scenario import Scenario

MISSION_DIR = "missions"


@dataclass
class Mission:
    """Waypoints in local metres, in the order they are flown."""

    name: str
    description: str
    waypoints: np.ndarray  # (n, 2) x east, y north
    loop: bool = True


def _centred(half: float, spacing: float) -> np.ndarray:
    n = int(2.0 * half / spacing + 1e-6) + 1
    return (np.arange(n) - 0.5 * (n - 1)) * spacing


def lawnmower(
    box: tuple[float, float, float, float],
    flow_dir_deg: float,
    orientation: str = "parallel",
    spacing: float = 20.0,
    start: str = "downstream",
) -> np.ndarray:
    """Boustrophedon legs over ``box`` along (parallel) or across (perpendicular) the flow direction."""
    x0, x1, y0, y1 = box
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    a = math.radians(flow_dir_deg)
    fx, fy = math.sin(a), math.cos(a)  # downstream unit vector
    px, py = fy, -fx  # to the right of the flow
    corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]) - (cx, cy)
    s_along = corners @ (fx, fy)
    s_across = corners @ (px, py)
    # the box is given in x/y; shrink the rotated extents so legs stay inside it
    half_along = float(np.min(np.abs(s_along)))
    half_across = float(np.min(np.abs(s_across)))
    if orientation == "parallel":
        offsets = _centred(half_across, spacing)
        legs = [((-half_along, o), (half_along, o)) for o in offsets]
    elif orientation == "perpendicular":
        offsets = _centred(half_along, spacing)
        legs = [((o, -half_across), (o, half_across)) for o in offsets]
        if start == "downstream":
            legs = legs[::-1]
    else:
        raise ValueError(f"orientation must be parallel or perpendicular, not {orientation!r}")
    pts: list[tuple[float, float]] = []
    for i, (p, q) in enumerate(legs):
        if orientation == "parallel":
            first_up = start == "downstream"
            go_up = first_up if i % 2 == 0 else not first_up
            p, q = (q, p) if go_up else (p, q)
        elif i % 2 == 1:
            p, q = q, p
        pts += [p, q]
    out = np.array([[cx + s * fx + c * px, cy + s * fy + c * py] for s, c in pts])
    return out


def builtin_names() -> list[str]:
    root = resources.files("forcemap.sim_devices") / MISSION_DIR
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def _read(name_or_path: str) -> tuple[dict[str, Any], str]:
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        return tomllib.loads(p.read_text()), p.stem
    res = resources.files("forcemap.sim_devices") / MISSION_DIR / f"{name_or_path}.toml"
    if not res.is_file():
        raise ValueError(
            f"unknown mission {name_or_path!r}; built in: {', '.join(builtin_names())}"
        )
    return tomllib.loads(res.read_text()), name_or_path


def load(name_or_path: str | Mission, scenario: Scenario) -> Mission:
    """A built-in mission by name or a mission TOML by path, laid out in ``scenario``."""
    if isinstance(name_or_path, Mission):
        return name_or_path
    data, name = _read(name_or_path)
    m = data.get("mission", {})
    kind = m.get("kind", "waypoints")
    if kind == "lawnmower":
        box = m.get("box", "survey")
        box = scenario.survey_box if box == "survey" else tuple(float(v) for v in box)
        wps = lawnmower(
            box,  # type: ignore[arg-type]
            float(m.get("direction_deg", scenario.flow_dir_deg)),
            str(m.get("orientation", "parallel")),
            float(m.get("spacing", 20.0)),
            str(m.get("start", "downstream")),
        )
    elif "latlon" in m:
        geo = Geo(scenario.lat0, scenario.lon0)
        ll = np.array(m["latlon"], dtype=float)
        wps = np.column_stack(geo.to_local(ll[:, 0], ll[:, 1]))
    else:
        wps = np.array(m["points"], dtype=float)
    if len(wps) < 2:
        raise ValueError(f"mission {name} needs at least two waypoints")
    return Mission(name, str(m.get("description", "")), wps, bool(m.get("loop", True)))


def describe_all() -> list[tuple[str, str]]:
    out = []
    for n in builtin_names():
        data, _ = _read(n)
        out.append((n, str(data.get("mission", {}).get("description", ""))))
    return out
