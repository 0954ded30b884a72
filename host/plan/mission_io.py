"""Missions in and out of the planner: QGC WPL 110 or simulator TOML in, WPL + TOML + JSON out, in lat/lon.

Inside the planner everything is in the survey's local frame (metres east/north of the survey centre,
`vessel.geodesy.LocalFrame`, as in the workbench); files carry latitude and longitude, so a mission planned
on one survey flies in any tool at the same place.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from forcemap.host.errors import CliError
from forcemap.host.outputs import atomic_path, atomic_write
from forcemap.host.vessel import mission as ms
from forcemap.host.vessel import qgc_plan
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel import waypoints as wp
from forcemap.host.vessel.geodesy import LocalFrame

LINE_FRACTION = (
    0.4  # without explicit lines, legs at least this share of the longest are survey lines
)


@dataclass
class MissionIn:
    """A mission as read: waypoints and intended lines in lat/lon, speeds per leg (NaN: cruise)."""

    name: str
    latlon: np.ndarray  # (n, 2)
    speeds: np.ndarray  # (n,)
    lines_latlon: np.ndarray  # (k, 2, 2)
    items: list | None = None  # a file's mission items (home first), DO_ items too
    plan_doc: dict | None = None  # a QGC .plan's document: its other fields go back out with it


PARALLEL_DEG = 20.0  # legs within this of one another's direction (either way) are parallel
GROUP_SHARE = 0.6  # a direction whose legs add up to this share of the main one's is surveyed too


def survey_lines(wps: np.ndarray) -> np.ndarray:
    """The legs that are survey lines: long parallel legs, not the short connectors between them.

    Legs are grouped by direction (within PARALLEL_DEG, either way); the group with the most length is
    the survey's direction (a cross-hatched survey's second direction counts if it has GROUP_SHARE of
    that length); its legs at least LINE_FRACTION as long as its longest are the lines. Connectors,
    lead-in and overshoot legs are shorter, or run across the lines and add up to less."""
    legs = np.stack([wps[:-1], wps[1:]], axis=1)
    return legs[survey_legs(legs)]


def survey_legs(legs: np.ndarray) -> np.ndarray:
    """Which of ``legs`` (k, 2, 2) are survey lines (``survey_lines``' rule), as a mask."""
    d = legs[:, 1] - legs[:, 0]
    length = np.hypot(*d.T)
    ang = np.degrees(np.arctan2(d[:, 0], d[:, 1])) % 180.0
    group = np.full(len(legs), -1)
    for k in np.argsort(-length):
        if group[k] >= 0 or length[k] < 1.0:
            continue
        diff = np.abs((ang - ang[k] + 90.0) % 180.0 - 90.0)
        group[(group < 0) & (diff <= PARALLEL_DEG) & (length >= 1.0)] = k
    totals = {g: float(length[group == g].sum()) for g in set(group.tolist()) if g >= 0}
    keep = np.zeros(len(legs), dtype=bool)
    best = max(totals.values(), default=0.0)
    for g, total in totals.items():
        if total >= GROUP_SHARE * best:
            keep |= (group == g) & (length >= LINE_FRACTION * length[g])
    return keep


def read_mission(path: str, scenario: str = "river") -> MissionIn:
    """A QGC WPL 110 file, or a simulator mission (TOML path or built-in name) laid out in ``scenario``."""
    try:
        scen = sc.load(scenario)
        m = ms.load(path, scen)
    except (ValueError, OSError) as e:
        raise CliError(f"cannot read the mission {path}: {e}") from e
    geo = LocalFrame(scen.lat0, scen.lon0)
    lat, lon = geo.to_latlon(m.waypoints[:, 0], m.waypoints[:, 1])
    lines = m.lines if m.lines is not None else survey_lines(m.waypoints)
    la, lo = geo.to_latlon(lines[..., 0], lines[..., 1])
    speeds = m.speeds if m.speeds is not None else np.full(len(lat), np.nan)
    doc = qgc_plan.read_plan(path)[3] if m.items is not None and qgc_plan.is_plan(path) else None
    return MissionIn(
        m.name, np.column_stack([lat, lon]), speeds, np.stack([la, lo], axis=-1), m.items, doc
    )


def output_paths(out: Path, plan: bool = False) -> tuple[Path, ...]:
    """OUT.waypoints, OUT.toml, OUT.json, and OUT.plan with ``plan`` (a suffix on OUT among those is
    dropped first)."""
    suffixes = (".waypoints", ".toml", ".json", ".plan")
    stem = out.with_suffix("") if out.suffix in suffixes else out
    return tuple(stem.with_name(stem.name + s) for s in suffixes[: 4 if plan else 3])


def write_outputs(
    out: Path,
    latlon: np.ndarray,
    speeds: np.ndarray,
    lines_latlon: np.ndarray,
    report: dict,
    description: str,
    plan_doc: dict | None = None,
) -> list[Path]:
    """OUT.waypoints (QGC WPL 110), OUT.toml (simulator), OUT.json (waypoints, lines, the prediction);
    OUT.plan too when the mission came as a QGC .plan (``plan_doc``: its other fields are kept)."""
    wpl, toml, js = output_paths(out)
    home, items = wp.waypoint(*latlon[0]), wp.items_for(latlon, speeds)
    with atomic_path(wpl) as tmp:
        wp.write_wpl(tmp, home, items)
    extra = []
    if plan_doc is not None:
        extra = [output_paths(out, plan=True)[3]]
        with atomic_write(extra[0]) as f:
            f.write(json.dumps(qgc_plan.plan_document(home, items, plan_doc), indent=4) + "\n")
    geo = LocalFrame(float(latlon[0, 0]), float(latlon[0, 1]))
    xy = np.column_stack(geo.to_local(latlon[:, 0], latlon[:, 1]))
    lxy = np.stack(geo.to_local(lines_latlon[..., 0], lines_latlon[..., 1]), axis=-1)
    mission = ms.Mission(wpl.stem, description, xy, False, speeds, lxy)
    with atomic_path(toml) as tmp:
        ms.save_toml(tmp, mission, geo)
    doc = ms.to_json(mission, geo)
    doc["plan"] = report
    with atomic_write(js) as f:
        f.write(json.dumps(doc, indent=1, default=_jsonable))
    return [wpl, toml, js, *extra]


def _jsonable(v):  # type: ignore[no-untyped-def]
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(type(v))


def mission_items(latlon: np.ndarray, speeds: np.ndarray, cruise: float) -> list[wp.Item]:
    """Mission items through ``latlon`` with an explicit ground speed on every leg (NaN: ``cruise``),
    so a part spliced after other items does not inherit their last DO_CHANGE_SPEED."""
    sp = np.where(np.isfinite(speeds), speeds, cruise)
    return wp.items_for(np.asarray(latlon, dtype=float), sp)


def nav_items(items: list[wp.Item]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lat/lon, leg speed, seq) of each NAV_WAYPOINT of ``items`` (home first, seq 0)."""
    latlon, speeds, seqs = wp.nav_points(items[1:])
    return latlon, speeds, seqs


def home_item(lat: float, lon: float) -> wp.Item:
    return wp.waypoint(lat, lon)
