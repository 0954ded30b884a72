"""A moving-boat ADCP transect as a survey: per ensemble, where the boat was, how deep the water,
and the water's velocity over ground through the profile, its depth average and near the surface.

From ``AdcpRaw`` (forcemap.host.convert.adcp_read):

- the clock: the instrument's time put on GPS UTC (``adcp_nav.clock_to_utc``);
- the compass: the offset that makes bottom track agree with GPS is estimated and applied to every
  earth-frame vector (``adcp_nav.fit_compass``); ``compass_offset`` pins it instead;
- the boat's velocity over ground: the bottom track's (``-vel_bt``) or the GPS's (``reference``),
  filled across gaps of at most ``MAX_FILL_S`` by linear interpolation (flagged), as QRev does, where
  the heading turned by at most ``MAX_FILL_TURN_DEG`` across the gap (not through a line's end turn);
- the water over ground in each cell: ``R(delta) vel + V_boat``; cells below the side-lobe cutoff
  (``range + cell/2 > (depth - draft) cos(beam angle)``) are left out;
- depth: the mean of the bottom-track beams' vertical ranges (at least 3) plus the draft; across a
  bottom-track gap of at most ``MAX_FILL_S`` it is interpolated for the cutoff and the depth average
  (and in the table's ``depth`` column);
- the depth average: a 1/6 power law ``u = a z^(1/6)`` (z above the bed) fitted per component to the
  valid cells and averaged over the whole column (QRev's default extrapolation to surface and bed);
- near the surface: the shallowest valid cell among the first ``NEAR_SURFACE_CELLS``;
- position: the GPS's, interpolated between fixes; else dead-reckoned on the boat's velocity from the
  nearest ensemble that has one (``position_dr`` = 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.convert.adcp_nav import (
    ClockFix,
    CompassFit,
    GpsTrack,
    clock_to_utc,
    displacements,
    fit_compass,
    gps_track,
    rotate,
)
from forcemap.host.convert.adcp_read import AdcpRaw

REFERENCES = ("bt", "gps")
POWER = 1.0 / 6.0
MAX_FILL_S = 10.0  # a boat velocity is interpolated across a gap of at most this
MAX_FILL_TURN_DEG = 20.0  # ... in which the heading turns by at most this
MIN_BT_BEAMS = 3
NEAR_SURFACE_CELLS = 3


@dataclass
class AdcpSurvey:
    """Per ensemble (n) and cell (m): the transect as the samples table and profile topic need it."""

    raw: AdcpRaw
    reference: str
    clock: ClockFix
    compass: CompassFit
    offset_applied: float  # the heading correction used (deg), 0 when none could be had
    t: np.ndarray  # UTC
    lat: np.ndarray
    lon: np.ndarray
    position_dr: np.ndarray  # 1 dead-reckoned, 0 GPS, NaN none
    depth: np.ndarray
    depth_filled: np.ndarray  # depth interpolated across bottom-track gaps of at most MAX_FILL_S
    heading: np.ndarray  # corrected
    bt_e: np.ndarray  # bottom-track boat velocity (corrected), NaN where no lock
    bt_n: np.ndarray
    gps_e: np.ndarray
    gps_n: np.ndarray
    boat_e: np.ndarray  # the reference's boat velocity, gaps filled
    boat_n: np.ndarray
    filled: np.ndarray  # bool: the boat velocity was interpolated here
    cell_depth: np.ndarray  # (m,) depth of each cell centre below the surface (median draft)
    cur_e: np.ndarray  # (m, n) water over ground, NaN where invalid
    cur_n: np.ndarray
    cur_u: np.ndarray
    davg_e: np.ndarray
    davg_n: np.ndarray
    ns_e: np.ndarray
    ns_n: np.ndarray
    notes: list[str] = field(default_factory=list)

    @property
    def has_ground_velocity(self) -> bool:
        return bool(np.isfinite(self.boat_e).any())


def bt_depth(dist_bt: np.ndarray, draft: np.ndarray) -> np.ndarray:
    """Depth below the surface: the mean of at least 3 beams' vertical ranges, plus the draft."""
    ok = np.isfinite(dist_bt)
    n = ok.sum(axis=0)
    mean = np.where(n > 0, np.nansum(np.where(ok, dist_bt, 0.0), axis=0) / np.maximum(n, 1), 0.0)
    return np.where(n >= MIN_BT_BEAMS, mean + draft, math.nan)


def fill_gaps(t: np.ndarray, v: np.ndarray, max_gap_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``v`` with runs of NaN no longer than ``max_gap_s`` interpolated, and where it did so."""
    ok = np.isfinite(v)
    out = v.copy()
    if ok.sum() < 2:
        return out, np.zeros(v.size, bool)
    ti = t[ok]
    k = np.searchsorted(ti, t)
    inner = ~ok & (k > 0) & (k < ti.size)
    kk = np.clip(k, 1, ti.size - 1)
    short = inner & (ti[kk] - ti[kk - 1] <= max_gap_s)
    out[short] = np.interp(t[short], ti, v[ok])
    return out, short


def steady_fill(filled: np.ndarray, valid: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """The filled ensembles whose gap the boat crossed without turning more than MAX_FILL_TURN_DEG
    (a velocity interpolated through a turn is wrong: the turns at a line's end are left empty)."""
    idx = np.flatnonzero(valid)
    out = filled.copy()
    for i in np.flatnonzero(filled):
        k = np.searchsorted(idx, i)
        if k == 0 or k >= idx.size:
            out[i] = False
            continue
        turn = abs((heading[idx[k]] - heading[idx[k - 1]] + 180.0) % 360.0 - 180.0)
        out[i] = bool(turn <= MAX_FILL_TURN_DEG)
    return out


def cell_mask(raw: AdcpRaw, depth: np.ndarray) -> np.ndarray:
    """(m, n) cells with a velocity and above the side-lobe cutoff (where the depth is known)."""
    finite = np.isfinite(raw.vel).all(axis=0)
    cutoff = (depth - raw.draft) * math.cos(math.radians(raw.beam_angle))
    edge = raw.range[:, None] + raw.cell_size / 2
    return finite & ~(edge > cutoff[None, :])


def depth_average(
    e: np.ndarray, n: np.ndarray, valid: np.ndarray, z: np.ndarray, water_depth: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The 1/6 power law fitted to each ensemble's valid cells, averaged over the water column.

    ``z`` (m, n) is each cell's height above the bed; the column's mean of ``a z^p`` over [0, D] is
    ``a D^p / (p + 1)``. At least 2 valid cells are needed.
    """
    zp = np.where(valid & (z > 0), z, 0.0) ** POWER
    w = np.where(valid & (z > 0), 1.0, 0.0)
    den = np.sum(w * zp * zp, axis=0)
    enough = (w.sum(axis=0) >= 2) & (den > 0) & np.isfinite(water_depth)
    scale = np.where(enough, water_depth**POWER / (POWER + 1) / np.where(den > 0, den, 1.0), 0.0)
    de = np.sum(w * zp * np.where(w > 0, e, 0.0), axis=0) * scale
    dn = np.sum(w * zp * np.where(w > 0, n, 0.0), axis=0) * scale
    return np.where(enough, de, math.nan), np.where(enough, dn, math.nan)


def near_surface(e: np.ndarray, n: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The shallowest valid cell among the first NEAR_SURFACE_CELLS of each ensemble."""
    top = valid[:NEAR_SURFACE_CELLS]
    has = top.any(axis=0)
    k = np.argmax(top, axis=0)
    cols = np.arange(e.shape[1])
    return np.where(has, e[k, cols], math.nan), np.where(has, n[k, cols], math.nan)


def _compass(raw: AdcpRaw, t: np.ndarray, track: GpsTrack, pinned: float | None) -> CompassFit:
    b, g, dt = displacements(t, -raw.vel_bt[0], -raw.vel_bt[1], track)
    fit = fit_compass(b, g, dt)
    if pinned is not None:
        fit.offset_deg, fit.sd_deg = float(pinned), 0.0
    return fit


def _positions(
    t: np.ndarray, track: GpsTrack, be: np.ndarray, bn: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lat, lon, flag): GPS between fixes, else dead-reckoned from the nearest GPS position."""
    n = t.size
    flag = np.full(n, math.nan)
    if track.frame is None:
        return np.full(n, math.nan), np.full(n, math.nan), flag
    x, y = track.ens_x.copy(), track.ens_y.copy()
    flag[track.bracketed] = 0.0
    dt = np.diff(t)
    for order in (range(1, n), range(n - 2, -1, -1)):  # forward from the last known, then back
        for i in order:
            j = i - 1 if order.step == 1 else i + 1
            if np.isfinite(x[i]) or not np.isfinite(x[j]):
                continue
            v_e = be[i] if np.isfinite(be[i]) else be[j]
            v_n = bn[i] if np.isfinite(bn[i]) else bn[j]
            if not (np.isfinite(v_e) and np.isfinite(v_n)):
                continue
            step = dt[min(i, j)] * (1 if order.step == 1 else -1)
            x[i], y[i] = x[j] + v_e * step, y[j] + v_n * step
            flag[i] = 1.0
    lat, lon = track.frame.to_latlon(x, y)
    return np.asarray(lat, float), np.asarray(lon, float), flag


def process(raw: AdcpRaw, reference: str = "bt", compass_offset: float | None = None) -> AdcpSurvey:
    """The transect from its raw ensembles (see the module docstring)."""
    if reference not in REFERENCES:
        raise ValueError(f"reference {reference!r} is not one of {REFERENCES}")
    clock = clock_to_utc(raw.t_gps, raw.t_gps_inst, raw.fix)
    t = raw.t_inst + clock.offset_s
    vtg = (raw.vtg_speed, raw.vtg_course) if raw.vtg_speed is not None else None
    track = gps_track(t, raw.t_gps, raw.lat, raw.lon, raw.fix, vtg)
    compass = _compass(raw, t, track, compass_offset)
    delta = compass.offset_deg if math.isfinite(compass.offset_deg) else 0.0
    bt_e, bt_n = rotate(-raw.vel_bt[0], -raw.vel_bt[1], delta)
    src = (bt_e, bt_n) if reference == "bt" else (track.vel_e, track.vel_n)
    boat_e, filled = fill_gaps(t, src[0], MAX_FILL_S)
    boat_n, _ = fill_gaps(t, src[1], MAX_FILL_S)
    keep = steady_fill(filled, np.isfinite(src[0]), raw.heading)
    boat_e[filled & ~keep] = boat_n[filled & ~keep] = math.nan
    filled = keep
    depth = bt_depth(raw.dist_bt, raw.draft)
    depth_filled, _ = fill_gaps(t, depth, MAX_FILL_S)  # the cutoff and the column's extent
    valid = cell_mask(raw, depth_filled)
    we, wn = rotate(raw.vel[0], raw.vel[1], delta)
    cur_e = np.where(valid, we + boat_e[None, :], math.nan)
    cur_n = np.where(valid, wn + boat_n[None, :], math.nan)
    cur_u = np.where(valid, raw.vel[2], math.nan)
    draft = float(np.nanmedian(raw.draft)) if np.isfinite(raw.draft).any() else 0.0
    z = (depth_filled - raw.draft)[None, :] - raw.range[:, None]
    good = valid & np.isfinite(cur_e) & np.isfinite(cur_n)
    davg_e, davg_n = depth_average(cur_e, cur_n, good, z, depth_filled)
    ns_e, ns_n = near_surface(cur_e, cur_n, good)
    lat, lon, flag = _positions(t, track, boat_e, boat_n)
    return AdcpSurvey(
        raw=raw,
        reference=reference,
        clock=clock,
        compass=compass,
        offset_applied=delta,
        t=t,
        lat=lat,
        lon=lon,
        position_dr=flag,
        depth=depth,
        depth_filled=depth_filled,
        heading=np.mod(raw.heading + delta, 360.0),
        bt_e=bt_e,
        bt_n=bt_n,
        gps_e=track.vel_e,
        gps_n=track.vel_n,
        boat_e=boat_e,
        boat_n=boat_n,
        filled=filled,
        cell_depth=raw.range + draft,
        cur_e=cur_e,
        cur_n=cur_n,
        cur_u=cur_u,
        davg_e=davg_e,
        davg_n=davg_n,
        ns_e=ns_e,
        ns_n=ns_n,
    )
