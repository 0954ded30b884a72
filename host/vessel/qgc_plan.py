"""QGroundControl's `.plan` files (JSON) as mission items, in and out (issue 31).

A `.plan` holds ``mission.items``: ``SimpleItem``s (one MAVLink mission item each: command, frame,
``params`` = param1-4, latitude, longitude, altitude; null for an unused value) and ``ComplexItem``s
(a survey, a corridor scan, a structure scan) whose ``TransectStyleComplexItem.Items`` are the simple
items QGC generated for them and uploads. Home is ``mission.plannedHomePosition`` [lat, lon, alt].

Read: every simple item, a complex item's generated items in their place; a survey's transects
(``VisualTransectPoints``, entry and exit of each) are its survey lines. Written: every item as a
``SimpleItem`` (a complex item becomes the simple items it stands for), the rest of the file as it was
(``geoFence``, ``rallyPoints``, ``groundStation``, ``mission.cruiseSpeed``, ``firmwareType``, ...).
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from .waypoints import Item

ROVER = 10  # MAV_TYPE_GROUND_ROVER
ARDUPILOT = 3  # MAV_AUTOPILOT_ARDUPILOTMEGA


def is_plan(path: str | Path) -> bool:
    """Whether ``path`` is a QGC .plan file (by its suffix, or a JSON object with fileType Plan)."""
    p = Path(path)
    if p.suffix == ".plan":
        return True
    if not p.is_file():
        return False
    head = p.read_bytes()[:200].lstrip()
    return head.startswith(b"{") and b'"fileType"' in head and b'"Plan"' in head


def _num(v: Any) -> float:
    return float("nan") if v is None else float(v)


def _item(d: dict) -> Item:
    p = [_num(v) for v in (list(d.get("params", [])) + [None] * 7)[:7]]
    return Item(
        int(d["command"]),
        0.0 if math.isnan(p[4]) else p[4],
        0.0 if math.isnan(p[5]) else p[5],
        0.0 if math.isnan(p[6]) else p[6],
        tuple(0.0 if math.isnan(v) else v for v in p[:4]),  # type: ignore[arg-type]
        int(d.get("frame", 3)),
    )


def read_plan(path: str | Path) -> tuple[Item, list[Item], np.ndarray | None, dict]:
    """(home, mission items, the surveys' transects as lines (k, 2, 2) lat/lon or None, the document);
    ValueError with the reason if it is not a .plan."""
    try:
        doc = json.loads(Path(path).read_text())
        if doc.get("fileType") != "Plan":
            raise ValueError("fileType is not Plan")
        mission = doc["mission"]
        raw = mission["items"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ValueError(f"{path}: not a QGC .plan file ({e})") from e
    items: list[Item] = []
    lines: list[list[list[float]]] = []
    try:
        for d in raw:
            if d.get("type") == "ComplexItem":
                ts = d.get("TransectStyleComplexItem") or {}
                items += [_item(x) for x in ts.get("Items", [])]
                pts = ts.get("VisualTransectPoints") or []
                lines += [[pts[k][:2], pts[k + 1][:2]] for k in range(0, len(pts) - 1, 2)]
            else:
                items.append(_item(d))
        home_ll = mission.get("plannedHomePosition") or [0.0, 0.0, 0.0]
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise ValueError(f"{path}: a mission item of the .plan is malformed ({e})") from e
    if not items:
        raise ValueError(f"{path}: the .plan has no mission items")
    home = Item(16, float(home_ll[0]), float(home_ll[1]), float(home_ll[2] or 0.0))
    arr = np.array(lines, dtype=float).reshape(-1, 2, 2) if lines else None
    return home, items, arr, doc


def simple_item(it: Item, jump_id: int) -> dict:
    """One mission item as a QGC ``SimpleItem``."""
    positioned = it.command < 80 or it.lat or it.lon  # a NAV_ command, or an item with a place
    params: list[float | None] = [float(v) for v in it.params]
    params += [it.lat, it.lon, it.alt] if positioned else [0.0, 0.0, 0.0]
    out: dict[str, Any] = {
        "autoContinue": True,
        "command": int(it.command),
        "doJumpId": jump_id,
        "frame": int(it.frame),
        "params": params,
        "type": "SimpleItem",
    }
    if it.frame == 3 and positioned:  # QGC's own fields for a waypoint relative to home
        out.update({"AMSLAltAboveTerrain": None, "Altitude": it.alt, "AltitudeMode": 1})
    return out


def plan_document(home: Item, items: list[Item], template: dict | None = None) -> dict:
    """A .plan document of ``items``: the ``template``'s other fields kept, or a fresh Rover plan."""
    doc = copy.deepcopy(template) if template else {
        "fileType": "Plan", "groundStation": "forcemap", "version": 1,
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "mission": {"cruiseSpeed": 3.5, "firmwareType": ARDUPILOT, "hoverSpeed": 5,
                    "vehicleType": ROVER, "version": 2},
    }  # fmt: skip
    mission = doc.setdefault("mission", {})
    mission["items"] = [simple_item(it, k + 1) for k, it in enumerate(items)]
    if not template or "plannedHomePosition" not in mission:
        mission["plannedHomePosition"] = [home.lat, home.lon, home.alt]
    return doc


def write_plan(
    path: str | Path, home: Item, items: list[Item], template: dict | None = None
) -> None:
    """Write ``items`` as a .plan (every item a SimpleItem; the template's other fields kept)."""
    Path(path).write_text(json.dumps(plan_document(home, items, template), indent=4) + "\n")
