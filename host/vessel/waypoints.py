"""QGC WPL 110 waypoint files (what Mission Planner and QGroundControl save) as mission items, via pymavlink.

Item 0 of a file is the home position (ArduPilot's convention); the mission proper starts at item 1.
Only NAV_WAYPOINT and DO_CHANGE_SPEED are flown by the simulator; other commands are kept and skipped.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pymavlink import mavwp
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

NAV_WAYPOINT = mavlink2.MAV_CMD_NAV_WAYPOINT
DO_CHANGE_SPEED = mavlink2.MAV_CMD_DO_CHANGE_SPEED
FRAME = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT


@dataclass
class Item:
    """One mission item, as in a MISSION_ITEM_INT (lat/lon in degrees here)."""

    command: int
    lat: float = 0.0
    lon: float = 0.0
    alt: float = 0.0
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    frame: int = FRAME
    comment: str = field(default="", compare=False)

    @property
    def lat_e7(self) -> int:
        return int(round(self.lat * 1e7))

    @property
    def lon_e7(self) -> int:
        return int(round(self.lon * 1e7))


def waypoint(lat: float, lon: float, comment: str = "") -> Item:
    return Item(NAV_WAYPOINT, float(lat), float(lon), comment=comment)


def change_speed(speed: float, comment: str = "") -> Item:
    """DO_CHANGE_SPEED: param1 speed type 1 (ground speed), param2 the speed in m/s, param3 -1 (throttle unchanged)."""
    return Item(DO_CHANGE_SPEED, params=(1.0, float(speed), -1.0, 0.0), frame=2, comment=comment)


def read_wpl(path: str | Path) -> tuple[Item, list[Item]]:
    """(home, mission items) of a QGC WPL 110 file; ValueError with the reason if it is not one."""
    loader = mavwp.MAVWPLoader()
    try:
        n = loader.load(str(path))
    except (mavwp.MAVWPError, ValueError, IndexError) as e:
        raise ValueError(f"{path}: not a QGC WPL 110 waypoint file ({e})") from e
    if n < 2:
        raise ValueError(f"{path}: needs a home item and at least one mission item, has {n}")
    items = []
    for i in range(n):
        w = loader.wp(i)
        items.append(
            Item(
                int(w.command),
                float(w.x),
                float(w.y),
                float(w.z),
                (float(w.param1), float(w.param2), float(w.param3), float(w.param4)),
                int(w.frame),
                getattr(w, "comment", "") or "",
            )
        )
    return items[0], items[1:]


def write_wpl(path: str | Path, home: Item, items: list[Item]) -> None:
    """Write a QGC WPL 110 file: home as item 0, then ``items`` (comments go on lines starting with #)."""
    loader = mavwp.MAVWPLoader()
    for seq, it in enumerate([home, *items]):
        # the MAVLink 1 fields only: the same call works whichever dialect mavutil has loaded
        msg = mavlink2.MAVLink_mission_item_message(
            0, 0, seq, it.frame if seq else 0, it.command, int(seq == 0), 1,
            *it.params, it.lat, it.lon, it.alt,
        )  # fmt: skip
        loader.add(msg, it.comment or None)
    loader.save(str(path))


def nav_points(items: list[Item]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lat/lon of each NAV_WAYPOINT (n, 2), the ground speed commanded on the leg into it (NaN: default),
    and its mission sequence number (``items`` start at seq 1: item 0 is home)."""
    pts, speeds, seqs = [], [], []
    speed = float("nan")
    for seq, it in enumerate(items, start=1):
        if it.command == DO_CHANGE_SPEED and it.params[1] > 0:
            speed = float(it.params[1])
        elif it.command == NAV_WAYPOINT:
            pts.append((it.lat, it.lon))
            speeds.append(speed)
            seqs.append(seq)
    return (
        np.array(pts, dtype=float).reshape(-1, 2),
        np.array(speeds, dtype=float),
        np.array(seqs, dtype=int),
    )


def items_for(latlon: np.ndarray, speeds: np.ndarray | None = None, comments=None) -> list[Item]:  # type: ignore[no-untyped-def]
    """NAV_WAYPOINTs through ``latlon``, with a DO_CHANGE_SPEED before a waypoint whose leg speed changes."""
    out: list[Item] = []
    last = float("nan")
    for i, (lat, lon) in enumerate(latlon):
        s = float("nan") if speeds is None else float(speeds[i])
        if np.isfinite(s) and not (np.isfinite(last) and abs(s - last) < 1e-6):
            out.append(change_speed(s))
            last = s
        out.append(waypoint(lat, lon, comments[i] if comments else ""))
    return out
