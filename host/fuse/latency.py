"""Each source's latency, from every pair that can tell: one least-squares solve over the lags.

A lag between two sources (source_stats.best_lag: the cross-correlation peak of offset-free signals)
is the difference of their latencies. Position is the time reference (a receiver stamps its fix in
UTC): the course over ground's rate of turn ties the headings and rates of turn to it. Every compass
against every rate-of-turn sensor (or autopilot gyro) and every other compass adds a pair; the
latencies are the weighted least-squares solution of all pairs (weight: the correlation peak), so a
compass 5 s late is told from an on-time one by the rate-of-turn sensor and the other compass, not
by one comparison alone. A source no pair reaches (directly or through others) has no latency:
nothing in the log can tell, and it is said so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from forcemap.host.fuse.source_stats import GRID_S, MIN_SOG, Track, best_lag, signal

MAX_LAG_S = 15.0  # a latency beyond this is a clock problem, not a latency


@dataclass
class Latency:
    """One source's latency (s, positive: late), its uncertainty and how it was found."""

    source: str
    value: float | None
    sd: float | None
    pairs: list[tuple[str, float]]  # (the other source or "position", its lag behind it, s)
    note: str = ""


def course_rate(t: np.ndarray, ve: np.ndarray, vn: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """The course over ground's rate of turn (deg/s) on ``grid``, NaN when slow: shape (n, 1)."""
    e, n = np.interp(grid, t, ve), np.interp(grid, t, vn)
    cog = np.degrees(np.unwrap(np.arctan2(e, n)))
    rate = np.gradient(cog, GRID_S)
    rate[np.hypot(e, n) < MIN_SOG] = np.nan
    return rate[:, None]


def _edges(
    signals: dict[str, np.ndarray], ref: np.ndarray | None
) -> list[tuple[str, str, float, float]]:
    """(a, b, lag of b behind a, weight) for every pair; "" is the position's course rate."""
    names = list(signals)
    out = []
    allsig = ([("", ref)] if ref is not None else []) + [(n, signals[n]) for n in names]
    for i, (a, sa) in enumerate(allsig):
        for b, sb in allsig[i + 1 :]:
            lag, peak = best_lag(sa, sb, MAX_LAG_S)
            if lag is not None and peak is not None and abs(lag) < MAX_LAG_S - GRID_S:
                out.append((a, b, lag, float(peak)))
    return out


def solve(names: list[str], edges: list[tuple[str, str, float, float]]) -> dict[str, Latency]:
    """The latencies (position = 0) that best explain the pairwise lags; None where no pair ties a
    source to the position."""
    reach = {""}
    changed = True
    while changed:
        changed = False
        for a, b, _, _ in edges:
            if (a in reach) != (b in reach):
                reach |= {a, b}
                changed = True
    known = [n for n in names if n in reach]
    out = {
        n: Latency(n, None, None, [], "no pair ties it to the position: nothing can tell")
        for n in names
        if n not in reach
    }
    if not known:
        return out
    col = {n: i for i, n in enumerate(known)}
    rows, y, w = [], [], []
    for a, b, lag, peak in edges:
        if a not in reach or b not in reach:
            continue
        r = np.zeros(len(known))
        if b:
            r[col[b]] += 1.0
        if a:
            r[col[a]] -= 1.0
        rows.append(r)
        y.append(lag)
        w.append(peak**2)
    a_mat, yv, wv = np.array(rows), np.array(y), np.sqrt(np.array(w))
    sol, *_ = np.linalg.lstsq(a_mat * wv[:, None], yv * wv, rcond=None)
    resid = a_mat @ sol - yv
    dof = len(yv) - len(known)
    scale = math.sqrt(float((wv**2 * resid**2).sum()) / dof) if dof > 0 else math.nan
    cov = np.linalg.pinv((a_mat * wv[:, None]).T @ (a_mat * wv[:, None]))
    for n, i in col.items():
        pairs = [(b or "position", -lag) for a, b, lag, _ in edges if a == n]
        pairs += [(a or "position", lag) for a, b, lag, _ in edges if b == n]
        sd = scale * math.sqrt(max(cov[i, i], 0.0)) if math.isfinite(scale) else None
        out[n] = Latency(n, float(sol[i]), sd, pairs)
    return out


def heading_latencies(
    headings: dict[str, Track],
    rates: dict[str, Track],
    velocity: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
) -> dict[str, Latency]:
    """Latencies of every compass and rate-of-turn source: each pair's lag, and the course over
    ground's rate of turn from the smoothed ground ``velocity`` (t, v_east, v_north)."""
    tracks = {**headings, **rates}
    if not tracks:
        return {}
    t0 = min(float(tr.t[0]) for tr in tracks.values() if len(tr.t))
    t1 = max(float(tr.t[-1]) for tr in tracks.values() if len(tr.t))
    grid = np.arange(t0, t1, GRID_S)
    signals = {}
    for name, tr in headings.items():
        if len(tr.t) > 2:
            signals[name] = signal("heading", tr, grid, (0.0, 0.0))
    for name, tr in rates.items():
        if len(tr.t) > 2:
            signals[name] = signal("yaw_rate", tr, grid, (0.0, 0.0))
    ref = None
    if velocity is not None and len(velocity[0]) > 2:
        tv, ve, vn = velocity
        ref = course_rate(tv, ve, vn, grid)
        ref[(grid < tv[0]) | (grid > tv[-1])] = np.nan
    out = solve(list(tracks), _edges(signals, ref))
    return _no_source_early(out)


def _no_source_early(out: dict[str, Latency]) -> dict[str, Latency]:
    """No instrument reports the future: where the solution has a heading source early against the
    course over ground, the course lags the heading (the hull's sideslip follows the turn), and the
    earliest source is taken as on time; the others keep their lags behind it."""
    known = [x.value for x in out.values() if x.value is not None]
    if not known or min(known) >= 0.0:
        return out
    lead = -min(known)
    for x in out.values():
        if x.value is not None:
            x.value += lead
            x.note = (
                f"the course over ground lags the headings by {lead:.2f} s (sideslip): "
                "the earliest heading source is taken as on time"
            )
    return out
