"""The records the live view publishes and never logs (`forcemap run --live`): `/health`, `/map/info`,
`/map/mission`.

The MCAP is the same with or without the live view; `messages.record_type` knows these topics too.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from forcemap.host.log.record import FoxgloveLog, GeoJSON, Record

Opt = float | None


@dataclass(slots=True)
class Health(Record):
    """What `/health` carries, once a second: per source, the live server, the disk."""

    NAME = "forcemap.Health"
    DESCRIPTION = (
        "Per source: state, bytes/s, seconds since the last reading, outages; the live "
        "server's clients and drops; disk space left; the alerts now active"
    )
    t: float
    sources: dict[str, Any]
    live: dict[str, Any]
    disk_free_bytes: int | None
    alerts: list[str] = field(default_factory=list)


@dataclass(slots=True)
class MapInfo(Record):
    """What one `/map/<target>` grid is: its frame, how many samples, how old, how uncertain."""

    NAME = "forcemap.MapInfo"
    DESCRIPTION = (
        "A live map's grid: origin (x0, y0, m east/north of lat0, lon0), step, size; "
        "samples so far, age of the fit and of its hyperparameters (s), value and sd ranges"
    )
    target: str
    t: float
    lat0: float
    lon0: float
    x0: float
    y0: float
    step: float
    nx: int
    ny: int
    n_samples: int
    age_s: float
    hyper_age_s: float
    fields: list[str]
    value_min: Opt = None
    value_max: Opt = None
    sd_max: Opt = None
    reason: str = ""


# published live only (`forcemap run --live`), never logged: the MCAP is the same with or without
# the live view; ``/map/<target>`` and ``/map/layers/<layer>`` are by prefix in `record_type`
LIVE_TOPIC_TYPES: dict[str, type[Record]] = {
    "/health": Health,
    "/alerts": FoxgloveLog,
    "/map/info": MapInfo,
    "/map/mission": GeoJSON,  # the mission on the Map panel (host/live/mission_layer.py)
}
MAP_TARGETS = ("current", "wind", "depth")
