"""Missions: waypoint lists or generated lawnmower patterns parallel or perpendicular to the flow."""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from forcemap.host.vessel import qgc_plan, waypoints
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.vessel.scenario import Scenario

MISSION_DIR = "missions"


@dataclass
class Mission:
    """Waypoints in local metres, in the order they are flown."""

    name: str
    description: str
    waypoints: np.ndarray  # (n, 2) x east, y north
    loop: bool = True
    speeds: np.ndarray | None = (
        None  # (n,) ground speed (m/s) on the leg into each waypoint; NaN: cruise
    )
    lines: np.ndarray | None = (
        None  # (k, 2, 2) the intended survey lines, if the mission was planned
    )
    seqs: np.ndarray | None = (
        None  # mission item sequence number of each waypoint (MISSION_CURRENT)
    )
    items: list | None = None  # the mission items as a file gave them (home first), DO_ items too


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
    root = resources.files("forcemap.host.vessel") / MISSION_DIR
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def _sidecar_lines(path: Path) -> dict[str, Any]:
    """The intended lines of a planned waypoint file, from the FILE.json written beside it (if any)."""
    side = path.with_suffix(".json")
    try:
        doc = json.loads(side.read_text())
        if (
            doc.get("lines_given") is False
        ):  # every leg, written for a mission with no lines of its own
            return {}
        return {"lines_latlon": [ln["latlon"] for ln in doc["lines"]]}
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def _from_items(p: Path, home: waypoints.Item, items: list, lines: np.ndarray | None, kind: str):  # type: ignore[no-untyped-def]
    latlon, speeds, seqs = waypoints.nav_points(items)
    m: dict[str, Any] = {
        "latlon": latlon.tolist(),
        "speeds": speeds.tolist(),
        "seqs": seqs.tolist(),
    }
    m["loop"] = False
    m["items"] = [home, *items]
    if lines is not None:  # a .plan survey's transects
        m["lines_latlon"] = lines.tolist()
    else:
        m.update(_sidecar_lines(p))
    return {"mission": {"description": f"{kind} {p.name}", **m}}, p.stem


def read_items(path: str | Path) -> tuple[waypoints.Item, list[waypoints.Item]]:
    """(home, mission items) of a QGC WPL 110 or .plan file (ValueError if it is neither)."""
    if qgc_plan.is_plan(path):
        home, items, _, _ = qgc_plan.read_plan(path)
        return home, items
    return waypoints.read_wpl(path)


def _read(name_or_path: str) -> tuple[dict[str, Any], str]:
    p = Path(name_or_path)
    if p.suffix == ".waypoints" or (p.is_file() and p.read_bytes()[:7] == b"QGC WPL"):
        home, items = waypoints.read_wpl(p)
        return _from_items(p, home, items, None, "waypoint file")
    if qgc_plan.is_plan(p):
        home, items, lines, _ = qgc_plan.read_plan(p)
        return _from_items(p, home, items, lines, "QGC plan")
    if p.suffix == ".toml" or p.exists():
        return tomllib.loads(p.read_text()), p.stem
    res = resources.files("forcemap.host.vessel") / MISSION_DIR / f"{name_or_path}.toml"
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
        geo = LocalFrame(scenario.lat0, scenario.lon0)
        ll = np.array(m["latlon"], dtype=float)
        wps = np.column_stack(geo.to_local(ll[:, 0], ll[:, 1]))
    else:
        wps = np.array(m["points"], dtype=float)
    if len(wps) < 2:
        raise ValueError(f"mission {name} needs at least two waypoints")
    speeds = lines = None
    if "speeds" in m:
        speeds = np.array([np.nan if v is None else v for v in m["speeds"]], dtype=float)
        if speeds.shape != (len(wps),):
            raise ValueError(f"mission {name}: speeds needs one value per waypoint")
    if "lines_latlon" in m:
        geo = LocalFrame(scenario.lat0, scenario.lon0)
        ll = np.array(m["lines_latlon"], dtype=float).reshape(-1, 2, 2)
        lines = np.stack(geo.to_local(ll[..., 0], ll[..., 1]), axis=-1)
    elif "lines" in m:
        lines = np.array(m["lines"], dtype=float).reshape(-1, 2, 2)
    seqs = np.array(m["seqs"], dtype=int) if "seqs" in m else None
    return Mission(
        name, str(m.get("description", "")), wps, bool(m.get("loop", True)), speeds, lines, seqs,
        m.get("items"),
    )  # fmt: skip


def from_items(items: list[waypoints.Item], geo: LocalFrame, start: tuple[float, float]) -> Mission:
    """A mission received over MAVLink (home first), flown from the boat's position ``start``."""
    latlon, speeds, seqs = waypoints.nav_points(items[1:])
    if len(latlon) == 0:
        raise ValueError("the mission has no NAV_WAYPOINT")
    wps = np.column_stack(geo.to_local(latlon[:, 0], latlon[:, 1]))
    return Mission(
        "uploaded",
        f"{len(items)} items received over MAVLink",
        np.vstack([np.asarray(start, dtype=float), wps]),
        False,
        np.concatenate([[speeds[0]], speeds]),
        None,
        np.concatenate([[seqs[0]], seqs]),
    )


def save_toml(path: str | Path, mission: Mission, geo: LocalFrame) -> None:
    """The mission in the simulator's TOML format (lat/lon, so it flies in any scenario at that place)."""
    lat, lon = geo.to_latlon(mission.waypoints[:, 0], mission.waypoints[:, 1])
    rows = ",\n  ".join(f"[{a:.8f}, {b:.8f}]" for a, b in zip(lat, lon, strict=True))
    out = [
        "[mission]",
        f"description = {json.dumps(mission.description)}",
        f"loop = {'true' if mission.loop else 'false'}",
        f"latlon = [\n  {rows},\n]",
    ]
    if mission.speeds is not None:
        vals = ", ".join("nan" if not np.isfinite(v) else f"{v:.3f}" for v in mission.speeds)
        out.append(f"speeds = [{vals}]  # ground speed on the leg into each waypoint; nan: cruise")
    if mission.lines is not None:
        la, lo = geo.to_latlon(mission.lines[..., 0], mission.lines[..., 1])
        segs = ",\n  ".join(
            f"[[{la[i, 0]:.8f}, {lo[i, 0]:.8f}], [{la[i, 1]:.8f}, {lo[i, 1]:.8f}]]"
            for i in range(len(la))
        )
        out.append(f"lines_latlon = [\n  {segs},\n]  # the intended survey lines")
    Path(path).write_text("\n".join(out) + "\n")


def save_waypoints(path: str | Path, mission: Mission, geo: LocalFrame) -> None:
    """The mission as a QGC WPL 110 file (home at the first waypoint), or its file's items if it has them."""
    if mission.items is not None:
        waypoints.write_wpl(path, mission.items[0], mission.items[1:])
        return
    lat, lon = geo.to_latlon(mission.waypoints[:, 0], mission.waypoints[:, 1])
    latlon = np.column_stack([lat, lon])
    waypoints.write_wpl(
        path, waypoints.waypoint(*latlon[0]), waypoints.items_for(latlon, mission.speeds)
    )


def intended_lines(mission: Mission) -> np.ndarray:
    """The lines the mission is meant to survey: its own, or else every leg between waypoints."""
    if mission.lines is not None:
        return mission.lines
    return np.stack([mission.waypoints[:-1], mission.waypoints[1:]], axis=1)


def to_json(mission: Mission, geo: LocalFrame) -> dict[str, Any]:
    """Waypoints and intended lines in lat/lon and local metres (the truth's mission.json)."""
    lat, lon = geo.to_latlon(mission.waypoints[:, 0], mission.waypoints[:, 1])
    lines = intended_lines(mission)
    la, lo = geo.to_latlon(lines[..., 0], lines[..., 1])
    speeds = mission.speeds if mission.speeds is not None else np.full(len(lat), np.nan)
    return {
        "name": mission.name,
        "loop": mission.loop,
        "lines_given": mission.lines is not None,  # else "lines" are every leg
        "lat0": geo.lat0,
        "lon0": geo.lon0,
        "waypoints": [
            {"lat": float(a), "lon": float(b), "x": float(x), "y": float(y),
             "speed": None if not np.isfinite(s) else float(s)}
            for a, b, (x, y), s in zip(lat, lon, mission.waypoints, speeds, strict=True)
        ],
        "lines": [
            {"latlon": [[float(la[i, j]), float(lo[i, j])] for j in range(2)],
             "xy": lines[i].tolist()}
            for i in range(len(lines))
        ],
    }  # fmt: skip


def describe_all() -> list[tuple[str, str]]:
    out = []
    for n in builtin_names():
        data, _ = _read(n)
        out.append((n, str(data.get("mission", {}).get("description", ""))))
    return out
