"""The navigation models, one home for the log smoother and the daemon's live filter.

What a source's readings say and how much they are trusted: each receiver's stated noise (its fix
class and HDOP, never below its minutes' quantisation), the constant-velocity process noises,
positions far from their neighbours screened out from the start, a ground velocity from SOG and
COG, a position sentence's own UTC time field, and the channels (forcemap.host.fuse.smoother) each
source becomes. forcemap.host.convert.navigation smooths a whole log with them;
forcemap.host.fuse.live_nav a sliding window of the daemon's readings (docs/NAVIGATION.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from forcemap.host.fuse import source_stats
from forcemap.host.fuse.smoother import Channel

Q_POSITION = 0.5  # m^2/s^3 without ground velocity readings (turning at 3 m/s: 0.5 m/s^2)
Q_HEADING = 50.0  # deg^2/s^3
POSITION_GAP_S = 12.0  # a row further than this from any position reading keeps its own
HEADING_GAP_S = 5.0
# a fix's stated noise (m, per axis, at HDOP 1) by its class (fix_quality.FIX_NAMES): the usual
# user-equivalent range errors of each kind of fix; the data decide where a receiver states nothing
UERE_M = {1: 10.0, 2: 4.0, 3: 2.0, 4: 0.5, 5: 0.2, 6: 0.02}
JUMP_M = 200.0  # a position this far from its neighbours' median is an outlier from the start
VELOCITY_FLOOR = 0.03  # m/s: no SOG is better than this, whatever its decimals say
MIN_VELOCITY_LAG_S = 0.5  # a smaller lag of a ground velocity is not told from its noise
MIN_VELOCITY_R = 0.7  # a velocity source's lag is taken from a clear correlation peak only
# the acceleration's density from the ground-velocity readings (acceleration_density): from a
# sailing boat on a steady reach (0.001) to a jet boat's turns (about 0.5)
Q_RANGE = (1e-3, 2.0)  # m^2/s^3
MIN_Q_READINGS = 30
MAX_Q_GAP_S = 10.0
MIN_DT_S = 0.05
G = 9.81  # m/s^2
SINGER = 4.0  # Singer's white density over the velocity increments' measure, at T = tau
SAME_FIX_S = 0.5  # one receiver's RMC, GGA and GLL of one fix are stamped 0.2-0.4 s apart
DAY = 86400.0
MAX_UTC_SKEW_S = 30.0
TIME_FIELD = {"RMC": 1, "GGA": 1, "GLL": 5, "GNS": 1}


def fix_noise(fix_class: int | None, hdop: float | None, decimals: int) -> float | None:
    """The noise (m, per axis) a receiver's fix states: UERE_M of its class times its HDOP, never
    below its minutes' quantisation (a step over the square root of 12); None where unknown."""
    uere = UERE_M.get(int(fix_class)) if fix_class is not None else None
    if uere is None:
        return None
    step = 1852.0 * 10.0**-decimals if decimals else 0.0
    return max(uere * max(hdop if hdop is not None else 1.0, 0.5), step / math.sqrt(12.0))


def screen(xy: np.ndarray) -> np.ndarray:
    """Positions far from the running median of their neighbours (jumps): weight 0 from the start."""
    n = len(xy)
    bad = np.zeros(n, bool)
    if not n:
        return bad
    med = np.median(xy, axis=0)
    far = np.hypot(*(xy - med).T)
    bad |= far > max(50_000.0, 20 * float(np.median(far)))
    k = min(31, n if n % 2 else n - 1)
    if k >= 5:
        from numpy.lib.stride_tricks import sliding_window_view

        pad = np.pad(xy, ((k // 2, k // 2), (0, 0)), mode="edge")
        mx = np.median(sliding_window_view(pad[:, 0], k), axis=1)
        my = np.median(sliding_window_view(pad[:, 1], k), axis=1)
        bad |= np.hypot(xy[:, 0] - mx, xy[:, 1] - my) > JUMP_M
    return bad


def velocity(sog: np.ndarray, cog: np.ndarray) -> np.ndarray:
    """(n, 2) east and north of speeds and courses (compass degrees)."""
    c = np.radians(cog)
    return np.column_stack([sog * np.sin(c), sog * np.cos(c)])


def near(t_read: np.ndarray, t: np.ndarray, gap: float) -> np.ndarray:
    """Whether each of ``t`` has a reading within ``gap``."""
    if not len(t_read):
        return np.zeros(len(t), bool)
    s = np.sort(t_read)
    i = np.clip(np.searchsorted(s, t), 1, len(s) - 1) if len(s) > 1 else np.zeros(len(t), int)
    d = np.minimum(np.abs(s[i] - t), np.abs(s[np.maximum(i - 1, 0)] - t))
    return d <= gap


# --- the channels each source becomes ----------------------------------------------------------------


def position_channels(
    name: str, t: np.ndarray, xy: np.ndarray, vel: np.ndarray | None, prior: float | None
) -> list[Channel]:
    """A receiver's positions (local metres, (n, 2)) and, where it gives them, its ground velocity
    readings (``vel``: (n, 2) east/north, NaN where none): a value and a rate channel."""
    c = Channel(name, "value", t, xy, sigma0=3.0, floor=0.05, prior_sigma=prior)
    c.weights_ = np.where(screen(xy), 0.0, 1.0) if len(xy) else np.ones(0)
    out = [c]
    if vel is not None:
        ok = np.isfinite(vel[:, 0]) & np.isfinite(vel[:, 1])
        if ok.sum() > 2:
            out.append(velocity_channel(name, t[ok], vel[ok]))
    return out


def velocity_channel(name: str, t: np.ndarray, vel: np.ndarray) -> Channel:
    """A ground velocity source (SOG and COG as east/north m/s): a rate of the position."""
    return Channel(name, "rate", t, vel, sigma0=0.3, floor=VELOCITY_FLOOR)


def heading_channel(name: str, kind: str, t: np.ndarray, v: np.ndarray, latency: float) -> Channel:
    """A compass (``kind`` "value", degrees) or a rate-of-turn sensor ("rate", deg/s)."""
    c = Channel(name, kind, t, v, latency=latency, sigma0=2.0, floor=0.1)
    if kind == "rate":
        c.bias_free, c.sigma0, c.floor = False, 1.0, 0.05
    return c


def unwrapped(t: np.ndarray, deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A compass's finite readings, unwrapped: the first estimate angles are unwrapped against."""
    ok = np.isfinite(deg)
    return t[ok], np.degrees(np.unwrap(np.radians(deg[ok])))


def velocity_latencies(channels: list[Channel]) -> dict[int, tuple[float | None, str]]:
    """Each ground-velocity channel's lag behind the positions (the velocity vector against the
    positions' change, source_stats.best_lag), by ``id`` of the channel: (lag, note); the note is
    empty where the lag is clear and large enough to remove (a filtered or relayed SOG)."""
    values = [c for c in channels if c.kind == "value" and c.n > 10]
    if not values:
        return {}
    ref_c = max(values, key=lambda c: c.n)
    ok = ref_c.weights_ > 0
    pos = source_stats.Track("p", ref_c.t[ok], ref_c.z[ok])
    grid_s = source_stats.GRID_S
    out: dict[int, tuple[float | None, str]] = {}
    for c in channels:
        if c.kind != "rate" or c.n < 10:
            continue
        vel = source_stats.Track("v", c.t, c.z)
        grid = source_stats._grid(pos, vel)
        if not len(grid):
            continue
        ref = np.stack(
            [np.gradient(source_stats._on_grid(pos.t, pos.v[:, j], grid), grid_s) for j in (0, 1)],
            axis=1,
        )
        sig = np.stack([source_stats._on_grid(vel.t, vel.v[:, j], grid) for j in (0, 1)], axis=1)
        lag, peak = source_stats.best_lag(ref, sig, 15.0)
        if lag is None or peak is None or peak < MIN_VELOCITY_R:
            r = "" if peak is None else f" (r = {peak:.2f})"
            out[id(c)] = (None, f"no clear lag against the positions{r}")
            continue
        small = abs(lag) < MIN_VELOCITY_LAG_S
        out[id(c)] = (float(lag), "within the estimate's noise: not removed" if small else "")
    return out


# --- a position sentence's own time ----------------------------------------------------------------


def time_of_day(text: str, stype: str) -> float | None:
    """The UTC time of day (s) of a position sentence, or None."""
    star = text.rfind("*")
    fields = text[1 : star if star > 0 else len(text)].split(",")
    i = TIME_FIELD.get(stype)
    if i is None or i >= len(fields):
        return None
    f = fields[i]
    try:
        return int(f[0:2]) * 3600 + int(f[2:4]) * 60 + float(f[4:])
    except ValueError:
        return None


def on_day(log_t: float, tod: float) -> float | None:
    """The UTC instant of time of day ``tod`` nearest to ``log_t``, if within MAX_UTC_SKEW_S."""
    day = np.floor(log_t / DAY) * DAY
    best = min((day + k * DAY + tod for k in (-1, 0, 1)), key=lambda x: abs(x - log_t))
    return float(best) if abs(best - log_t) <= MAX_UTC_SKEW_S else None


def coarse_stamps(t: Sequence[float], latlon: np.ndarray, moved_deg: float) -> bool:
    """Whether a receiver's stamps repeat for different positions (a stamp every 10 s on fixes
    every 2 s): it is then timed by its log times, not by them."""
    if len(t) < 3:
        return False
    same_t = np.diff(np.asarray(t, float)) == 0
    moved = np.any(np.abs(np.diff(latlon[:, :2], axis=0)) > moved_deg, axis=1)
    return bool((same_t & moved).sum() > 0.1 * len(t))


def acceleration_density(channels: list[Channel]) -> float | None:
    """The white acceleration's spectral density (m^2/s^3, per axis) the log's own ground-velocity
    readings show, or None without them. Over an interval ``tau`` a boat's velocity changes by
    ``a tau`` (a turn's acceleration is smooth: Singer's model, variance ``s2`` correlated over
    ``T``), so ``|dv|^2 / (2 tau)`` per axis measures ``s2 tau / 2``, and the white density that
    model equals is ``2 s2 T``: ``SINGER`` (4) times the measure with ``T = tau``, ``tau`` the
    longest interval the track has to bridge (the slowest receiver's between fixes). The mean over
    each source's readings ``tau`` apart (manoeuvres included: q is the acceleration's mean power);
    a reading's own noise only adds to it, so each source's figure is an upper bound and the least
    is kept. Increments beyond 1 g (no boat turns or brakes harder: a garbled reading) and across
    silences longer than MAX_Q_GAP_S do not count. Bounded to Q_RANGE."""
    tau = float(np.clip(max(map(_fix_interval, channels), default=1.0), MIN_DT_S, MAX_Q_GAP_S / 2))
    found = []
    for c in channels:
        if c.kind != "rate" or c.n < MIN_Q_READINGS:
            continue
        i = np.arange(c.n)
        j = np.searchsorted(c.t, c.t + tau - MIN_DT_S)
        i, j = i[j < c.n], j[j < c.n]
        dt = c.t[j] - c.t[i]
        a2 = ((c.z[j, :2] - c.z[i, :2]) ** 2).sum(axis=1)
        ok = (dt <= MAX_Q_GAP_S) & (a2 <= (G * dt) ** 2)
        if ok.sum() >= MIN_Q_READINGS:
            found.append(SINGER * float(np.mean(a2[ok] / (2 * dt[ok]))))
    if not found:
        return None
    return float(np.clip(min(found), *Q_RANGE))


def _fix_interval(c: Channel) -> float:
    """The median interval between a receiver's fixes (its sentences of one fix, stamped within
    SAME_FIX_S of each other, are one); 0 for a velocity source."""
    if c.kind != "value" or c.n < 3:
        return 0.0
    dt = np.diff(c.t)
    apart = dt[dt > SAME_FIX_S]
    return float(np.median(apart if len(apart) else dt))
