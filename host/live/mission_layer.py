"""`/map/mission`: the mission on the live Map panel (foxglove.GeoJSON, lon/lat): the intended lines,
the plan the autopilot holds now (replaced on each accepted replan), and the flown track, decimated.

A view, never logged: the replanner hands in the mission (``set_plan``, from its own thread), the
publisher thread hands in every ``/fix`` (``fix``) and asks ``due`` whether to publish.
"""

from __future__ import annotations

import json
import math
import threading
from typing import Any

from forcemap.host.log.messages import GeoJSON
from forcemap.host.vessel.geodesy import LocalFrame

TOPIC = "/map/mission"
TRACK_STEP_M = 3.0  # a track point is kept once the boat is this far from the last one kept
TRACK_MAX = 4000  # beyond this, every other point is dropped (the track stays whole, only coarser)
EVERY_S = 5.0  # the track is republished at most this often (log time); a new plan goes out at once
STYLE = {
    "line": {"color": "#9467bd", "weight": 4},
    "plan": {"color": "#d62728", "weight": 2},
    "track": {"color": "#000000", "weight": 2},
}


def _metres(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Distance between two (lat, lon) points a few hundred metres apart."""
    x, y = LocalFrame(a[0], a[1]).to_local(b[0], b[1])
    return math.hypot(float(x), float(y))


def _line(points: list[tuple[float, float]], name: str, style: str) -> dict[str, Any]:
    coords = [[round(lon, 7), round(lat, 7)] for lat, lon in points]
    return {
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": coords},
        "properties": {"name": name, "style": STYLE[style]},
    }


class MissionLayer:
    """The three parts of the overlay, thread-safe; ``geojson`` is the document published."""

    def __init__(self, step_m: float = TRACK_STEP_M, every_s: float = EVERY_S):
        self.step_m, self.every_s = step_m, every_s
        self._lock = threading.Lock()
        self.lines: list[list[tuple[float, float]]] = []
        self.plan: list[tuple[float, float]] = []
        self.plans = 0  # how many plans were handed in: the first, then one per accepted upload
        self.track: list[tuple[float, float]] = []
        self._changed = False
        self._last_ns: int | None = None

    def set_plan(self, lines_latlon: Any, plan_latlon: Any) -> None:
        """The intended lines (pairs of (lat, lon) ends) and the waypoints the autopilot holds."""
        with self._lock:
            self.lines = [[(float(a[0]), float(a[1])), (float(b[0]), float(b[1]))]
                          for a, b in lines_latlon]  # fmt: skip
            self.plan = [(float(p[0]), float(p[1])) for p in plan_latlon]
            self.plans += 1
            self._changed = True
            self._last_ns = None  # publish at once

    def fix(self, lat: float, lon: float) -> None:
        if not (math.isfinite(lat) and math.isfinite(lon)):
            return
        with self._lock:
            if self.track and _metres(self.track[-1], (lat, lon)) < self.step_m:
                return
            self.track.append((lat, lon))
            if len(self.track) > TRACK_MAX:
                self.track = self.track[::2] + ([] if len(self.track) % 2 else [self.track[-1]])
            self._changed = True

    def due(self, t_ns: int) -> bool:
        """Whether something changed and the last publication is ``every_s`` old (or a plan is new);
        never before a mission is known (``run --replan``)."""
        with self._lock:
            if not self._changed or not self.plan:  # without a mission /fix draws the track
                return False
            if self._last_ns is not None and t_ns - self._last_ns < self.every_s * 1e9:
                return False
            self._last_ns, self._changed = t_ns, False
            return True

    def geojson(self) -> dict[str, Any]:
        with self._lock:
            feats = [_line(ln, f"intended line {k + 1}", "line") for k, ln in enumerate(self.lines)]
            if len(self.plan) >= 2:
                name = "plan: the original" if self.plans <= 1 else f"plan: replan {self.plans - 1}"
                feats.append(_line(self.plan, name, "plan"))
            if len(self.track) >= 2:
                feats.append(_line(self.track, "flown track", "track"))
        return {"type": "FeatureCollection", "features": feats}

    def message(self) -> GeoJSON:
        return GeoJSON(json.dumps(self.geojson(), separators=(",", ":")))
