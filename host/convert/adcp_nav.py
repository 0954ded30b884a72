"""The ADCP's navigation: its clock on GPS UTC, GPS positions and velocities per ensemble, and the
compass offset (and a moving bed) from the redundancy between bottom track and GPS.

Velocities are (east, north) in m/s. A compass offset ``delta`` is in compass degrees (clockwise),
added to the instrument's heading: a vector measured with the raw heading is turned by ``delta``
(``rotate``). The offset is the one that makes the bottom track's displacement between consecutive
GPS fixes agree with the GPS's in the least-squares sense (a closed form); where the track turns
enough to tell them apart, a second fit (Pollard & Read's, linear in ``A cos delta, A sin delta``
and a constant) also estimates a scale and the bed's steady velocity under the bottom track: a
moving bed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame

MAX_FIX_GAP_S = 30.0  # positions and GPS velocities are interpolated across gaps up to this
MIN_FIX_QUALITY = 1  # GGA quality 0 is no fix
MIN_TURN_R = 0.9  # mean resultant length of the track's directions below which the track turned


@dataclass
class ClockFix:
    """The instrument's clock on GPS UTC: ``t_utc = t_inst + offset_s``."""

    offset_s: float
    spread_s: float  # the interquartile range of the per-fix offsets (latency jitter)
    fixes: int
    without_fix: int = 0  # GGA of quality 0 left out: a receiver without a fix times it by its own clock


def clock_to_utc(
    t_gps: np.ndarray, t_gps_inst: np.ndarray, fix: np.ndarray | None = None
) -> ClockFix:
    """The median offset between each fix's UTC and the instrument time of its ensemble; a GGA
    that says it has no fix (``fix`` quality 0) never sets the clock (issue 60), unless no GGA has
    one (a quality left empty counts as a fix)."""
    d = t_gps - t_gps_inst
    ok = np.isfinite(d)
    dropped = 0
    if fix is not None and fix.size == d.size:
        good = ok & (np.where(np.isfinite(fix), fix, MIN_FIX_QUALITY) >= MIN_FIX_QUALITY)
        if good.any():
            dropped, ok = int(ok.sum() - good.sum()), good
    d = d[ok]
    if not d.size:
        return ClockFix(0.0, math.nan, 0)
    q1, q3 = np.percentile(d, [25, 75])
    return ClockFix(float(np.median(d)), float(q3 - q1), int(d.size), dropped)


def rotate(east: np.ndarray, north: np.ndarray, delta_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(east, north) turned clockwise by ``delta_deg`` (a heading correction applied)."""
    c, s = math.cos(math.radians(delta_deg)), math.sin(math.radians(delta_deg))
    return east * c + north * s, -east * s + north * c


@dataclass
class GpsTrack:
    """The good fixes in a local frame, and per ensemble: position and velocity where reachable."""

    frame: LocalFrame | None
    t: np.ndarray  # good fixes' UTC
    x: np.ndarray
    y: np.ndarray
    bracketed: np.ndarray  # (n,) bool: the ensemble lies between fixes at most MAX_FIX_GAP_S apart
    ens_x: np.ndarray
    ens_y: np.ndarray
    vel_e: np.ndarray  # (n,) GPS velocity at each ensemble (VTG where recorded, else fix to fix)
    vel_n: np.ndarray


def good_fixes(lat: np.ndarray, lon: np.ndarray, fix: np.ndarray) -> np.ndarray:
    """Fixes with a position and a quality of at least 1."""
    q = np.where(np.isfinite(fix), fix, MIN_FIX_QUALITY)
    return np.isfinite(lat) & np.isfinite(lon) & (q >= MIN_FIX_QUALITY) & ((lat != 0) | (lon != 0))


def gps_track(
    t_ens: np.ndarray,
    t_gps: np.ndarray,
    lat: np.ndarray,
    lon: np.ndarray,
    fix: np.ndarray,
    vtg: tuple[np.ndarray, np.ndarray] | None,
) -> GpsTrack:
    """Positions interpolated between fixes, and the GPS velocity, at every ensemble's UTC."""
    n = t_ens.size
    nan = np.full(n, math.nan)
    ok = good_fixes(lat, lon, fix) & np.isfinite(t_gps)
    if ok.sum() < 2:
        return GpsTrack(None, t_gps[ok], nan[:0], nan[:0], np.zeros(n, bool), nan, nan, nan, nan)
    tg = t_gps[ok]
    order = np.argsort(tg)
    tg = tg[order]
    frame = LocalFrame(float(lat[ok][order][0]), float(lon[ok][order][0]))
    x, y = (np.asarray(a, dtype=float) for a in frame.to_local(lat[ok][order], lon[ok][order]))
    k = np.clip(np.searchsorted(tg, t_ens, side="right") - 1, 0, tg.size - 2)
    gap = tg[k + 1] - tg[k]
    inside = (t_ens >= tg[0]) & (t_ens <= tg[-1]) & (gap <= MAX_FIX_GAP_S) & (gap > 0)
    w = np.where(inside, (t_ens - tg[k]) / np.where(gap > 0, gap, 1.0), math.nan)
    ex = x[k] + w * (x[k + 1] - x[k])
    ey = y[k] + w * (y[k + 1] - y[k])
    ve = np.where(inside, (x[k + 1] - x[k]) / np.where(gap > 0, gap, 1.0), math.nan)
    vn = np.where(inside, (y[k + 1] - y[k]) / np.where(gap > 0, gap, 1.0), math.nan)
    if vtg is not None:
        spd, crs = vtg[0][ok][order], vtg[1][ok][order]
        good = np.isfinite(spd) & np.isfinite(crs)
        if good.sum() >= 2:
            e, nn = (
                spd[good] * np.sin(np.radians(crs[good])),
                spd[good] * np.cos(np.radians(crs[good])),
            )
            ve = np.where(inside, np.interp(t_ens, tg[good], e), math.nan)
            vn = np.where(inside, np.interp(t_ens, tg[good], nn), math.nan)
    return GpsTrack(frame, tg, x, y, inside, ex, ey, ve, vn)


@dataclass
class CompassFit:
    """The heading offset that makes bottom track agree with GPS, and what the turns tell besides."""

    offset_deg: float  # add to the instrument's heading
    sd_deg: float
    intervals: int  # fix-to-fix intervals used
    scale: float = math.nan  # the joint fit's bottom-track scale (1 = none)
    bed_east: float = math.nan  # the bed's steady velocity under the bottom track (moving bed)
    bed_north: float = math.nan
    bed_sd: float = math.nan
    joint_offset_deg: float = math.nan  # the joint fit's offset
    turned: bool = False  # the track turned enough to fit the scale and the bed separately
    track_r: float = math.nan  # mean resultant length of the track's directions (1 = straight)


def displacements(
    t_ens: np.ndarray, be: np.ndarray, bn: np.ndarray, track: GpsTrack
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per fix-to-fix interval with bottom track in every ensemble: (BT (k,2), GPS (k,2), dt (k,))."""
    dt_ens = np.gradient(t_ens) if t_ens.size > 1 else np.ones_like(t_ens)
    b, g, d = [], [], []
    for i in range(track.t.size - 1):
        t0, t1 = track.t[i], track.t[i + 1]
        if not 0 < t1 - t0 <= MAX_FIX_GAP_S:
            continue
        m = (t_ens > t0) & (t_ens <= t1)
        if not m.any() or not (np.isfinite(be[m]).all() and np.isfinite(bn[m]).all()):
            continue
        # the bottom track's displacement over the ensembles' own durations, scaled to the interval
        span = dt_ens[m].sum()
        s = (t1 - t0) / span if span > 0 else 0.0
        b.append((np.sum(be[m] * dt_ens[m]) * s, np.sum(bn[m] * dt_ens[m]) * s))
        g.append((track.x[i + 1] - track.x[i], track.y[i + 1] - track.y[i]))
        d.append(t1 - t0)
    return np.asarray(b).reshape(-1, 2), np.asarray(g).reshape(-1, 2), np.asarray(d)


def fit_compass(b: np.ndarray, g: np.ndarray, dt: np.ndarray) -> CompassFit:
    """The offset turning BT displacements ``b`` onto GPS ones ``g``; the joint fit where it turned."""
    k = len(b)
    if k < 2 or not np.any(np.hypot(b[:, 0], b[:, 1]) > 0):
        return CompassFit(math.nan, math.nan, k)
    cross = np.sum(b[:, 0] * g[:, 1] - b[:, 1] * g[:, 0])
    dot = np.sum(b[:, 0] * g[:, 0] + b[:, 1] * g[:, 1])
    delta = -math.degrees(math.atan2(cross, dot))
    re, rn = rotate(b[:, 0], b[:, 1], delta)
    res2 = np.sum((g[:, 0] - re) ** 2 + (g[:, 1] - rn) ** 2)
    sd = math.degrees(math.sqrt(res2 / max(1, 2 * k - 1) / max(np.sum(b**2), 1e-12)))
    fit = CompassFit(delta, sd, k)
    norm = np.hypot(b[:, 0], b[:, 1])
    moving = norm > 0
    unit = b[moving] / norm[moving, None]
    fit.track_r = float(np.hypot(*unit.mean(axis=0))) if moving.any() else math.nan
    fit.turned = bool(k >= 6 and fit.track_r < MIN_TURN_R)
    if fit.turned:
        _joint(fit, b, g, dt)
    return fit


def _joint(fit: CompassFit, b: np.ndarray, g: np.ndarray, dt: np.ndarray) -> None:
    """g = A R(delta) b + c dt, linear in (A cos delta, A sin delta, c_east, c_north)."""
    k = len(b)
    rows = np.zeros((2 * k, 4))
    rows[:k] = np.column_stack([b[:, 0], b[:, 1], dt, np.zeros(k)])
    rows[k:] = np.column_stack([b[:, 1], -b[:, 0], np.zeros(k), dt])
    rhs = np.concatenate([g[:, 0], g[:, 1]])
    sol, *_ = np.linalg.lstsq(rows, rhs, rcond=None)
    resid = rhs - rows @ sol
    s2 = float(resid @ resid) / max(1, 2 * k - 4)
    cov = s2 * np.linalg.pinv(rows.T @ rows)
    a, s, ce, cn = sol
    fit.scale = float(math.hypot(a, s))
    fit.joint_offset_deg = math.degrees(math.atan2(s, a))
    fit.bed_east, fit.bed_north = float(ce), float(cn)
    fit.bed_sd = float(math.sqrt(max(0.0, (cov[2, 2] + cov[3, 3]) / 2)))
