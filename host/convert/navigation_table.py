"""The samples table with every row at its own time: smoothed navigation, compensation done again.

Each row keeps its time and every measurement; its position, ground velocity, heading and yaw rate
become the smoothed state at that time (forcemap.host.convert.navigation), where a reading is near.
The speed through water is taken at the row's time plus the speed log's latency, and the true wind
and the current from the speed through water are computed again from them (the computed route of
the wind only; the paddle wheels' current is left as logged). Nothing is dropped: a row the smoother
has nothing for keeps its logged values. The log's boat file decides (``[sync] navigation`` and
``latency``), as logged in its ``calibration`` metadata.
"""

from __future__ import annotations

import ast
import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from forcemap.host.convert import nav_readings
from forcemap.host.convert.navigation import Navigation
from forcemap.host.fuse import compensation as comp
from forcemap.host.fuse.sources import AUTOPILOT_CONNECTIONS, split_name
from forcemap.host.log.mcap import iter_metadata, read_messages
from forcemap.host.log.messages import SAMPLE_COLUMNS


def log_metadata(paths: Sequence[str | os.PathLike[str]], name: str) -> dict[str, str]:
    """The last metadata record ``name`` of the logs (empty if none): from a complete file's
    summary, else by reading the file through (`iter_metadata`)."""
    found: dict[str, str] = {}
    for path in paths:
        for key, data in iter_metadata(path):
            if key == name:
                found = data
    return found


def settings(paths: Sequence[str | os.PathLike[str]]) -> tuple[str, str]:
    """(navigation, latency) of the logs' boat file: ``smoothed``/``logged``, ``remove``/``keep``."""
    cal = log_metadata(paths, "calibration")
    return cal.get("navigation", "smoothed"), cal.get("latency", "remove")


READING_TOPICS = (*nav_readings.TOPICS, "/current")
wanted = nav_readings.wanted
_CACHE: dict[tuple, Navigation | None] = {}  # the last smoothing of each log, for its findings


def _key(paths: Sequence[str | os.PathLike[str]], remove: bool) -> tuple:
    out: list[Any] = [remove]
    for p in paths:
        try:
            st = os.stat(p)
            out.append((os.path.abspath(p), st.st_mtime_ns, st.st_size))
        except OSError:
            out.append((str(p), 0, 0))
    return tuple(out)


def fitted(paths: Sequence[str | os.PathLike[str]]) -> Navigation | None:
    """The smoothing of these logs as their boat file asks (done again if it was not)."""
    mode, latency = settings(paths)
    key = _key(paths, mode != "logged" and latency != "keep")
    if key not in _CACHE:  # smoothed at the rows' times, as samples_table would
        t = []
        messages: list[tuple[str, int, dict]] = []
        for m in read_messages(paths, ("/samples", *READING_TOPICS), accept=wanted):
            if m.topic == "/samples":
                tt = m.message.get("t")
                t.append(float(tt) if isinstance(tt, int | float) else m.log_time_ns * 1e-9)
            else:
                messages.append((m.topic, m.log_time_ns, m.message))
        readings = nav_readings.collect(messages)
        nav = None
        if "position" in readings and t:
            remove = key[0] and not _autopilot(readings)
            nav = Navigation(remove_latency=remove).fit(readings, np.unique(np.asarray(t)))
        _CACHE[key] = nav
    return _CACHE.get(key)


def latencies(paths: Sequence[str | os.PathLike[str]]) -> dict[str, dict[str, Any]]:
    """Per source: quantity, latency (s or None), whether it was removed, and the note."""
    cols = log_metadata(paths, "columns")
    if cols.get("lat", "").split(" ", 1)[0] in AUTOPILOT_CONNECTIONS:
        return {}  # the rows keep the autopilot's fused navigation: no latency was removed or kept
    nav = fitted(paths)
    if nav is None:
        return {}
    return {
        f.source: {
            "quantity": f.quantity,
            "latency": f.latency,
            "removed": f.applied,
            "note": f.latency_note,
            "against": [a for a, _ in f.pairs],
        }
        for f in nav.fits_
        if f.quantity in ("heading", "yaw_rate", "stw")
    }


def _col(columns: list[str], rows: list[list[float | None]], name: str) -> np.ndarray:
    if name not in columns:
        return np.full(len(rows), np.nan)
    i = columns.index(name)
    return np.array([np.nan if r[i] is None else r[i] for r in rows], float)


def _stw(nav: Navigation, readings: dict, t: np.ndarray, stw: np.ndarray) -> np.ndarray:
    """The speed through water at each row's time plus the speed log's latency (its used source)."""
    lat = nav.stw_latency_
    used = [s for s in readings.get("stw", {}).values() if s.used]
    if lat is None or not nav.remove_latency or not used:
        return stw
    ts, vs = max(used, key=lambda s: s.used).arrays()
    ok = np.isfinite(vs[:, 0])
    if ok.sum() < 2:
        return stw
    out = np.interp(t + lat, ts[ok], vs[ok, 0], left=np.nan, right=np.nan)
    return np.where(np.isfinite(stw) & np.isfinite(out), out, stw)


def _compensate(cols: dict[str, np.ndarray], n: int, beta: float = 0.0) -> None:
    """True wind (from the apparent wind) and the current from the speed through water, again
    (``beta``: the speed log's misalignment the log was imported with, as the pipeline applies it:
    the water passes the hull at heading + beta)."""
    h, ve, vn = cols["heading"], cols["v_east"], cols["v_north"]
    for name in ("wind_east", "wind_north", "wind_speed", "wind_dir"):
        cols.setdefault(name, np.full(n, np.nan))
    for name in ("current_speed_stw", "current_dir_stw", "current_east", "current_north"):
        cols.setdefault(name, np.full(n, np.nan))
    for name in ("current_speed", "current_dir"):
        cols.setdefault(name, np.full(n, np.nan))
    wheels = np.isfinite(cols.get("wheel1_speed", np.full(n, np.nan)))
    aws, awa, stw = cols.get("app_wind_speed"), cols.get("app_wind_angle"), cols.get("stw")
    for i in range(n):
        if not (math.isfinite(h[i]) and math.isfinite(ve[i]) and math.isfinite(vn[i])):
            continue
        if aws is not None and awa is not None and math.isfinite(aws[i]) and math.isfinite(awa[i]):
            we, wn = comp.true_wind(aws[i], awa[i], h[i], ve[i], vn[i])
            cols["wind_east"][i], cols["wind_north"][i] = we, wn
            cols["wind_speed"][i], cols["wind_dir"][i] = (
                math.hypot(we, wn),
                comp.from_direction(we, wn),
            )
        if stw is not None and math.isfinite(stw[i]):
            ce, cn = comp.current_from_stw(stw[i], h[i] + beta, ve[i], vn[i])
            speed, direction = math.hypot(ce, cn), comp.to_direction(ce, cn)
            cols["current_speed_stw"][i], cols["current_dir_stw"][i] = speed, direction
            if not wheels[i]:
                cols["current_east"][i], cols["current_north"][i] = ce, cn
                cols["current_speed"][i], cols["current_dir"][i] = speed, direction


def _autopilot(readings: dict) -> bool:
    """Whether the rows' position came from an autopilot (MAVLink, DataFlash): fused already."""
    return any(
        s.used and split_name(name)[0] in AUTOPILOT_CONNECTIONS
        for name, s in readings.get("position", {}).items()
    )


def _wheels(cols: dict[str, Any], nav: Navigation, messages: list, cal: dict[str, str]) -> None:
    """The paddle wheels' current again: each row's flows (its ``/current`` record) turned with the
    smoothed heading and added to the smoothed ground velocity of half a rate window before (the
    wheels' rates describe the flow then: host/fuse/assembler.py)."""
    if "wheel1_speed" not in cols:
        return
    flows = {float(m["t"]): m for topic, _, m in messages if topic == "/current" and "t" in m}
    if not flows:
        return
    try:
        angles = [float(a) for _, a in ast.literal_eval(cal.get("wheels", "[]"))]
        lag = float(cal.get("rate_window_s", "1.0")) / 2
    except (ValueError, SyntaxError, TypeError):
        return
    t = cols["t"]
    st = nav.state(t - lag)
    for i in range(len(t)):
        m = flows.get(float(t[i]))
        h, ve, vn = st["heading"][i], st["v_east"][i], st["v_north"][i]
        if m is None or not (math.isfinite(h) and math.isfinite(ve) and math.isfinite(vn)):
            continue
        out = {}
        if m.get("flow_fwd") is not None and m.get("flow_stbd") is not None:
            out["lsq"] = comp.current_over_ground(m["flow_fwd"], m["flow_stbd"], h, ve, vn)
        wheels = m.get("wheels") or []
        if len(wheels) == len(angles) and all(w is not None for w in wheels):
            pf, ps = comp.current_paper(wheels, angles)
            out["paper"] = comp.current_over_ground(pf, ps, h, ve, vn)
        chosen = out.get(m.get("estimator", "lsq"))
        if chosen is not None:
            cols["current_east"][i], cols["current_north"][i] = chosen
            cols["current_speed"][i] = math.hypot(*chosen)
            cols["current_dir"][i] = comp.to_direction(*chosen)
        if "paper" in out and "current_speed_paper" in cols:
            cols["current_speed_paper"][i] = math.hypot(*out["paper"])
            cols["current_dir_paper"][i] = comp.to_direction(*out["paper"])


def smooth(
    columns: list[str],
    rows: list[list[float | None]],
    paths: Sequence[str | os.PathLike[str]],
    messages: list[tuple[str, int, dict]] | None = None,
    *,
    remove_latency: bool | None = None,
) -> tuple[list[str], list[list[float | None]], Navigation | None]:
    """``columns`` and ``rows`` (``t`` first) with the smoothed navigation; unchanged when the log
    has no navigation reading. ``messages``: the logs' READING_TOPICS messages (read here if None);
    ``remove_latency``: None follows the log's boat file."""
    if remove_latency is None:
        remove_latency = settings(paths)[1] != "keep"
    readings = nav_readings.read(paths) if messages is None else nav_readings.collect(messages)
    if "position" not in readings or not rows:
        _remember(paths, remove_latency, None)
        return columns, rows, None
    try:
        return _smooth(columns, rows, paths, readings, messages, remove_latency)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        # a log the smoother cannot solve keeps the rows the pipeline made (counted nowhere else:
        # `log info` says the navigation was not smoothed)
        _remember(paths, remove_latency, None)
        return columns, rows, None


def _remember(
    paths: Sequence[str | os.PathLike[str]], remove: bool, nav: Navigation | None
) -> None:
    """The smoothing of a log, for its findings (rows of no log yet are not kept)."""
    if not paths:
        return
    if len(_CACHE) > 8:
        _CACHE.clear()
    _CACHE[_key(paths, remove)] = nav


def _smooth(
    columns: list[str],
    rows: list[list[float | None]],
    paths: Sequence[str | os.PathLike[str]],
    readings: dict,
    messages: list[tuple[str, int, dict]] | None,
    remove_latency: bool,
) -> tuple[list[str], list[list[float | None]], Navigation | None]:
    n = len(rows)
    t = _col(columns, rows, "t")
    if _autopilot(readings):
        # an autopilot's navigation is its EKF's, already fused from its own sensors at their
        # times: the rows keep it (`log info` still measures the sources: fitted)
        return columns, rows, None
    nav = Navigation(remove_latency=remove_latency).fit(readings, t)
    _remember(paths, remove_latency, nav)
    cal = log_metadata(paths, "calibration")
    st = nav.state(t)
    cols: dict[str, Any] = {c: _col(columns, rows, c) for c in columns}
    for c in ("lat", "lon", "heading", "yaw_rate"):
        cols[c] = np.where(np.isfinite(st[c]), st[c], cols.get(c, np.full(n, np.nan)))
    logged_v = comp_velocity(cols.get("sog"), cols.get("cog"), n)
    ve = np.where(np.isfinite(st["v_east"]), st["v_east"], logged_v[0])
    vn = np.where(np.isfinite(st["v_north"]), st["v_north"], logged_v[1])
    cols["v_east"], cols["v_north"] = ve, vn
    cols["sog"] = np.hypot(ve, vn)
    cols["cog"] = np.degrees(np.arctan2(ve, vn)) % 360.0
    if "stw" in cols:
        cols["stw"] = _stw(nav, readings, t, cols["stw"])
    _compensate(cols, n, _float(cal.get("stw_misalignment_deg")))
    if messages is not None:
        _wheels(cols, nav, messages, cal)
    order = [c for c in SAMPLE_COLUMNS if c in cols]
    order += [c for c in cols if c not in order and c not in ("v_east", "v_north")]
    keep = [c for c in order if c == "t" or np.isfinite(cols[c]).any()]
    out = [
        [None if not math.isfinite(v) else float(v) for v in vals]
        for vals in zip(*(cols[c] for c in keep), strict=True)
    ]
    return keep, out, nav


def _float(text: str | None) -> float:
    """A number of a metadata record (written as its repr; "None" or none: 0)."""
    try:
        x = float(text or "nan")
    except ValueError:
        return 0.0
    return x if math.isfinite(x) else 0.0


def as_exported(
    rows: Sequence[dict[str, Any]], messages: list[tuple[str, int, dict]], remove_latency: bool
) -> list[dict[str, Any]]:
    """Sample rows not yet in a log (the calibrated import's first pass) with the navigation an
    export of their log gives them (``smooth``): ordered by ``t``, a repeated ``t`` dropped, each
    row's navigation smoothed from ``messages`` (READING_TOPICS, as logged) and its compensation
    done again. Cells that are not numbers are left out."""
    names: dict[str, None] = {"t": None}
    for r in rows:
        names.update(dict.fromkeys(r))
    columns = list(names)
    table: list[list[float | None]] = []
    for r in sorted(rows, key=lambda r: float(r["t"])):
        if table and table[-1][0] == float(r["t"]):
            continue
        table.append([_cell(r.get(c)) for c in columns])
    columns, table, _ = smooth(columns, table, (), messages, remove_latency=remove_latency)
    return [dict(zip(columns, r, strict=True)) for r in table]


def _cell(v: Any) -> float | None:
    """A cell as export keeps it: a finite number (a flag as 0 or 1), else None."""
    if not isinstance(v, int | float) or not math.isfinite(v):
        return None
    return float(v)


def comp_velocity(sog: Any, cog: Any, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The logged ground velocity (east, north) of the rows, NaN where it is missing."""
    if sog is None or cog is None:
        return np.full(n, np.nan), np.full(n, np.nan)
    c = np.radians(cog)
    return sog * np.sin(c), sog * np.cos(c)
