"""Consistency by redundancy: instrument scales, offsets and dead sources estimated from a log's own data.

Every estimator takes plain arrays of one log's samples (UNIX seconds, SI, compass degrees) and returns a
result with its uncertainty and the evidence it rests on; none decides what is applied (that is
``forcemap.host.convert.self_calibration``). The anchors (docs/QA.md):

- speed log: Pollard & Read (1989) / Joyce (1989), ``v_ground = A R(beta) v_water + c``: linear in
  ``(A cos beta, A sin beta)`` and one current ``c`` per window, solved by robust (Huber) least squares;
- rate of turn: the heading's change over short windows against the integrated rate, through the origin;
  a ratio near 60 is a rate sent in degrees per second where NMEA 0183 says per minute;
- heading against course over ground when going straight at speed (evidence of a compass offset);
- a dead source: constant while its partner varies (a speed log at 0.00 kn while the GPS says 3 m/s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PR_WINDOW_S = 600.0  # the current is taken constant over 10 min windows (a slowly varying current)
PR_MIN_SPEED = 1.0  # m/s through water and over ground: paddle-wheel logs are non-linear below
PR_MAX_TURN = 3.0  # deg/s: turning rows carry leeway and lag, left out
HUBER_K = 1.5  # Huber's constant, in robust standard deviations
JACK_GROUPS = 10  # contiguous stretches of the log for the jackknife's uncertainty
ROT_WINDOW_S = 10.0
ROT_MIN_CHANGE = 5.0  # deg of heading change over a window for it to inform the scale
DEAD_WINDOW_S = 60.0
DEAD_MIN_PARTNER = 1.0  # m/s: the partner must show the boat moving
DEAD_FLAT = 1e-3  # a reading whose range over a window is below this is constant
DEAD_PARTNER_VARIES = 0.5  # m/s: the partner's range over the stretch shows it alive
DEAD_ZERO = 0.05  # m/s: a log reading zero while the boat moves is dead whatever the partner does


def wrap180(a: np.ndarray) -> np.ndarray:
    """Angles (deg) into (-180, 180]."""
    return -((-np.asarray(a, float) + 180.0) % 360.0 - 180.0)


def _ne(speed: np.ndarray, direction_deg: np.ndarray) -> np.ndarray:
    """(north, east) components of a speed along a compass direction."""
    r = np.radians(direction_deg)
    return np.column_stack([speed * np.cos(r), speed * np.sin(r)])


def _neff_factor(res: np.ndarray) -> float:
    """How much the lag-1 autocorrelation of residuals inflates a variance ((1 + rho) / (1 - rho))."""
    if len(res) < 3 or np.std(res) == 0:
        return 1.0
    rho = float(np.corrcoef(res[:-1], res[1:])[0, 1])
    rho = min(max(rho, 0.0), 0.98)
    return (1 + rho) / (1 - rho)


def _huber_lstsq(a: np.ndarray, b: np.ndarray, iters: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Huber-weighted least squares: (solution, final weights)."""
    w = np.ones(len(b))
    x = np.zeros(a.shape[1])
    for _ in range(iters):
        sw = np.sqrt(w)
        x, *_ = np.linalg.lstsq(a * sw[:, None], b * sw, rcond=None)
        r = b - a @ x
        s = 1.4826 * np.median(np.abs(r)) + 1e-9
        u = np.abs(r) / (HUBER_K * s)
        w = np.where(u <= 1, 1.0, 1.0 / np.maximum(u, 1e-12))
    return x, w


def _jackknife(a: np.ndarray, b: np.ndarray, n: int) -> tuple[float, float]:
    """Delete-a-group jackknife sd of (gain, misalignment deg) over JACK_GROUPS stretches of the log:
    a current that drifts within a window, or a speed log that changes, shows here and not in the
    residuals' formula."""
    idx = np.array_split(np.arange(n), JACK_GROUPS)
    est = []
    for g in idx:
        keep = np.ones(n, bool)
        keep[g] = False
        rows = np.concatenate([keep, keep])
        sub = a[rows]
        used = np.abs(sub).sum(axis=0) > 0  # a window left with no rows drops its current
        x, _ = _huber_lstsq(sub[:, used], b[rows])
        est.append((math.hypot(x[0], x[1]), math.degrees(math.atan2(x[1], x[0]))))
    e = np.array(est)
    k = len(e)
    sd = np.sqrt((k - 1) / k * np.sum((e - e.mean(axis=0)) ** 2, axis=0))
    return float(sd[0]), float(sd[1])


@dataclass(frozen=True)
class SpeedLogFit:
    """Pollard & Read's amplitude factor and misalignment of a speed log, with their uncertainty."""

    gain: float
    gain_sd: float
    misalignment_deg: float  # clockwise: the water passes the hull at heading + beta
    misalignment_sd: float
    rows: int
    windows: int
    heading_spread_deg: float  # circular spread of the headings used (0: one course only)
    rms_residual: float  # m/s
    current_raw: tuple[float, float]  # mean (east, north) of ground - STW along the heading, m/s
    current_fit: tuple[float, float]  # mean of the fitted per-window currents, m/s


def fit_speed_log(
    t: np.ndarray,
    heading: np.ndarray,
    stw: np.ndarray,
    sog: np.ndarray,
    cog: np.ndarray,
    yaw_rate: np.ndarray | None = None,
    window_s: float = PR_WINDOW_S,
    min_speed: float = PR_MIN_SPEED,
) -> SpeedLogFit | None:
    """The speed log's gain and misalignment against the GPS velocity (None: too little to fit)."""
    ok = np.isfinite(t) & np.isfinite(heading) & np.isfinite(stw) & np.isfinite(sog)
    ok &= np.isfinite(cog) & (stw >= min_speed) & (sog >= min_speed)
    if yaw_rate is not None:
        ok &= ~(np.abs(np.nan_to_num(yaw_rate)) > PR_MAX_TURN)
    if ok.sum() < 60:
        return None
    t, h, w_s, g_s, c_d = t[ok], heading[ok], stw[ok], sog[ok], cog[ok]
    w = _ne(w_s, h)
    g = _ne(g_s, c_d)
    win = np.floor((t - t[0]) / window_s).astype(int)
    _, win = np.unique(win, return_inverse=True)
    m = int(win.max()) + 1
    n = len(t)
    # unknowns: a = A cos b, b = A sin b, then (c_n, c_e) per window
    a = np.zeros((2 * n, 2 + 2 * m))
    a[:n, 0], a[:n, 1] = w[:, 0], -w[:, 1]
    a[n:, 0], a[n:, 1] = w[:, 1], w[:, 0]
    a[np.arange(n), 2 + 2 * win] = 1.0
    a[n + np.arange(n), 3 + 2 * win] = 1.0
    b = np.concatenate([g[:, 0], g[:, 1]])
    x, wt = _huber_lstsq(a, b)
    r = b - a @ x
    keep = wt > 0
    dof = max(int(keep.sum()) - a.shape[1], 1)
    s2 = float(np.sum(wt * r**2) / dof) * max(_neff_factor(r[:n]), _neff_factor(r[n:]))
    aw = a * np.sqrt(wt)[:, None]
    cov = s2 * np.linalg.pinv(aw.T @ aw)
    ac, bs = x[0], x[1]
    gain = math.hypot(ac, bs)
    beta = math.atan2(bs, ac)
    # the Jacobian of (gain, beta) in (a, b)
    j = np.array([[ac / gain, bs / gain], [-bs / gain**2, ac / gain**2]])
    cg = j @ cov[:2, :2] @ j.T
    jg, jb = _jackknife(a, b, n)
    hr = np.radians(h)
    spread = math.degrees(
        math.sqrt(max(-2 * math.log(max(abs(np.mean(np.exp(1j * hr))), 1e-12)), 0))
    )
    raw = g - w
    cw = x[2:].reshape(m, 2)
    return SpeedLogFit(
        gain=gain,
        gain_sd=max(math.sqrt(max(cg[0, 0], 0.0)), jg),
        misalignment_deg=math.degrees(beta),
        misalignment_sd=max(math.degrees(math.sqrt(max(cg[1, 1], 0.0))), jb),
        rows=n,
        windows=m,
        heading_spread_deg=spread,
        rms_residual=float(np.sqrt(np.mean(r**2))),
        current_raw=(float(np.mean(raw[:, 1])), float(np.mean(raw[:, 0]))),
        current_fit=(float(np.mean(cw[:, 1])), float(np.mean(cw[:, 0]))),
    )


@dataclass(frozen=True)
class RateScale:
    """The heading's change over short windows against the integrated rate of turn."""

    scale: float  # heading change / integrated rate (1: they agree)
    scale_sd: float
    correlation: float
    windows: int
    unit: str  # "deg/min" (as NMEA 0183 says), "deg/s" (a vendor's: scale ~60), or "unknown"


def fit_rate_scale(
    t: np.ndarray, heading: np.ndarray, yaw_rate: np.ndarray, window_s: float = ROT_WINDOW_S
) -> RateScale | None:
    """Scale of a rate-of-turn reading against the heading's change (None: the boat never turned)."""
    ok = np.isfinite(t) & np.isfinite(heading) & np.isfinite(yaw_rate)
    if ok.sum() < 20:
        return None
    t, h, y = t[ok], heading[ok], yaw_rate[ok]
    hu = np.degrees(np.unwrap(np.radians(h)))
    dt = np.diff(t)
    step_ok = dt < 5.0
    integ = np.concatenate([[0.0], np.cumsum(np.where(step_ok, 0.5 * (y[1:] + y[:-1]) * dt, 0.0))])
    edges = np.arange(t[0], t[-1], window_s)
    i = np.searchsorted(t, edges)
    i = np.unique(i[i < len(t)])
    if len(i) < 3:
        return None
    i0, i1 = i[:-1], i[1:] - 1
    span = t[i1] - t[i0]
    gaps = np.add.reduceat(~step_ok, i0) if len(i0) else np.array([])
    good = (span > 0.5 * window_s) & (gaps[: len(i0)] == 0)
    dh = (hu[i1] - hu[i0])[good]
    dr = (integ[i1] - integ[i0])[good]
    use = np.abs(dh) >= ROT_MIN_CHANGE
    if use.sum() < 5:
        return None
    dh, dr = dh[use], dr[use]
    if np.sum(dr**2) == 0:
        return RateScale(math.inf, math.nan, 0.0, int(use.sum()), "unknown")
    x, wt = _huber_lstsq(dr[:, None], dh)
    scale = float(x[0])
    r = dh - scale * dr
    s2 = float(np.sum(wt * r**2) / max(len(r) - 1, 1))
    sd = math.sqrt(s2 / max(float(np.sum(wt * dr**2)), 1e-12))
    corr = float(np.corrcoef(dh, dr)[0, 1]) if np.std(dr) > 0 else 0.0
    return RateScale(scale, sd, corr, len(dh), rate_unit(scale))


def rate_unit(scale: float) -> str:
    """The unit a rate of turn was sent in, from its scale against the heading's change."""
    if 0.5 <= scale <= 2.0:
        return "deg/min"
    if 30.0 <= scale <= 120.0:
        return "deg/s"
    return "unknown"


@dataclass(frozen=True)
class HeadingCog:
    """Course over ground minus heading when going straight at speed: a compass offset plus leeway and
    current, evidence rather than a calibration."""

    offset_deg: float  # median (cog - heading)
    spread_deg: float  # robust standard deviation
    rows: int


def heading_vs_cog(
    heading: np.ndarray,
    cog: np.ndarray,
    sog: np.ndarray,
    yaw_rate: np.ndarray | None = None,
    min_speed: float = 1.5,
) -> HeadingCog | None:
    """Course over ground against heading on straight, fast stretches (None: none)."""
    ok = np.isfinite(heading) & np.isfinite(cog) & np.isfinite(sog) & (sog >= min_speed)
    if yaw_rate is not None:
        ok &= ~(np.abs(np.nan_to_num(yaw_rate)) > 1.0)
    if ok.sum() < 30:
        return None
    d = wrap180(cog[ok] - heading[ok])
    med = float(np.median(d))
    spread = float(1.4826 * np.median(np.abs(wrap180(d - med))))
    return HeadingCog(med, spread, int(ok.sum()))


@dataclass(frozen=True)
class DeadStretches:
    """Stretches where a source reads a constant while its partner shows the boat moving."""

    intervals: tuple[tuple[float, float], ...]  # (start, end) UNIX seconds
    seconds: float
    fraction: float  # of the time the partner shows the boat moving
    value: float  # the constant it read (the first stretch's)


def dead_stretches(
    t: np.ndarray,
    reading: np.ndarray,
    partner: np.ndarray,
    window_s: float = DEAD_WINDOW_S,
    min_partner: float = DEAD_MIN_PARTNER,
) -> DeadStretches:
    """Runs of at least ``window_s`` where ``reading`` stays constant while ``partner`` (e.g. SOG)
    shows the boat moving (median over ``min_partner``)."""
    ok = np.isfinite(t) & np.isfinite(partner) & np.isfinite(reading)
    t, x, p = t[ok], reading[ok], partner[ok]
    if len(t) < 2:
        return DeadStretches((), 0.0, 0.0, math.nan)
    moving = p >= min_partner
    dt = np.diff(t)
    moving_s = float(np.sum(np.where(moving[1:] & (dt < 5.0), dt, 0.0)))
    same = np.abs(np.diff(x)) < DEAD_FLAT
    out: list[tuple[float, float]] = []
    value = math.nan
    start = 0
    for k in range(1, len(t) + 1):
        if k < len(t) and same[k - 1]:
            continue
        a, b = start, k - 1  # a run of equal readings, rows a..b
        pp = p[a : b + 1]
        # zero while moving, or a constant while the partner varies (a damped log holds a steady
        # speed for a minute; a frozen bus repeats every sentence)
        spread = float(np.percentile(pp, 95) - np.percentile(pp, 5))
        varies = abs(float(x[a])) < DEAD_ZERO or spread >= DEAD_PARTNER_VARIES
        if t[b] - t[a] >= window_s and np.median(pp) >= min_partner and varies:
            out.append((float(t[a]), float(t[b])))
            value = float(x[a]) if math.isnan(value) else value
        start = k
    secs = sum(b - a for a, b in out)
    return DeadStretches(tuple(out), secs, secs / moving_s if moving_s else 0.0, value)
