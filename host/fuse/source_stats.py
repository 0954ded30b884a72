"""How the sources of one quantity compare: rate, share of the time, disagreement, lag and latency.

For every source of a quantity, against the chosen one: the median (signed) and p95 (absolute) of
their difference at the same instants, and the lag that best aligns them by cross-correlation of
a signal that does not depend on a constant offset (the velocity for positions, the rate of turn
for headings, the mean-removed value otherwise). Its latency is the same lag against the position
source: positions by their velocity, headings by the course over ground's rate of turn, speed
through water by the speed over ground (their accelerations). A positive lag or latency: the source is
late. An NMEA capture has no receive times (the import spreads its lines between the sentences' UTC
stamps), so there the figures are only as good as that spread.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame

GRID_S = 0.2
MAX_LAG_S = 30.0
MAX_GAP_S = 5.0  # no interpolation across a longer silence
MIN_OVERLAP = 50  # grid points in common for a lag to mean anything
MIN_SOG = 0.5  # m/s: below, the course over ground is noise
NEAR_S = 3.0
MIN_CORR = 0.3  # a correlation peak below this is not a lag: reported as none, with its value
ANGULAR = {"heading"}
UNITS = {
    "position": "m",
    "heading": "deg",
    "yaw_rate": "deg/s",
    "stw": "m/s",
    "depth": "m",
    "wind": "m/s",
    "wind_true": "m/s",
    "water_temp": "degC",
    "velocity": "m/s",
}


class Track:
    """One source's readings of one quantity: times (s) and value tuples, in time order."""

    def __init__(
        self,
        name: str,
        t: Iterable[float],
        v: Iterable[Sequence[Any]],
        used: int = 0,
        readings: int | None = None,
    ) -> None:
        order = np.argsort(np.asarray(list(t), dtype=float), kind="stable")
        tt = np.asarray(list(t), dtype=float)
        vals = list(v)
        self.name = name
        self.t = tt[order]
        width = max((len(x) for x in vals), default=1)
        arr = np.full((len(vals), width), np.nan)
        for i, x in enumerate(vals):
            arr[i, : len(x)] = [np.nan if y is None else float(y) for y in x]
        self.v = arr[order] if len(vals) else np.zeros((0, 1))
        self.used = used
        self.readings = len(self.t) if readings is None else readings  # before thinning

    def rate_hz(self) -> float:
        if len(self.t) < 2 or self.t[-1] <= self.t[0]:
            return 0.0
        return (self.readings - 1) / (self.t[-1] - self.t[0])

    def covered_s(self) -> float:
        """Seconds of the log this source speaks in: its intervals, a silence counting 3 of them."""
        if len(self.t) < 2:
            return 0.0
        dt = np.diff(self.t)
        typical = float(np.median(dt))
        return float(np.minimum(dt, 3.0 * max(typical, 1e-3)).sum())


def _metres(lat: np.ndarray, lon: np.ndarray, lat0: float, lon0: float) -> np.ndarray:
    x, y = LocalFrame(lat0, lon0).to_local(lat, lon)
    return np.stack([x, y], axis=1)


def _on_grid(t: np.ndarray, y: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """``y`` at ``grid`` by linear interpolation, NaN in silences longer than MAX_GAP_S."""
    ok = np.isfinite(y)
    t, y = t[ok], y[ok]
    if len(t) < 2:
        return np.full(len(grid), np.nan)
    out = np.interp(grid, t, y, left=np.nan, right=np.nan)
    i = np.clip(np.searchsorted(t, grid), 1, len(t) - 1)
    out[(t[i] - t[i - 1]) > MAX_GAP_S] = np.nan
    return out


def signal(quantity: str, tr: Track, grid: np.ndarray, origin: tuple[float, float]) -> np.ndarray:
    """The offset-free signal of a source on ``grid``: shape (n, k)."""
    if quantity == "position":
        xy = _metres(tr.v[:, 0], tr.v[:, 1], *origin)
        cols = [_on_grid(tr.t, xy[:, j], grid) for j in (0, 1)]
        return np.stack([np.gradient(c, GRID_S) for c in cols], axis=1)
    if quantity in ANGULAR:
        h = _on_grid(tr.t, np.degrees(np.unwrap(np.radians(tr.v[:, 0]))), grid)
        return np.gradient(h, GRID_S)[:, None]
    y = _on_grid(tr.t, tr.v[:, 0], grid)
    return (y - np.nanmean(y))[:, None] if np.isfinite(y).any() else y[:, None]


Lag = tuple[float | None, float | None]  # (lag s or None, the peak correlation or None)


def _score(ref: np.ndarray, sig: np.ndarray, k: int) -> float:
    """The correlation of ``sig`` shifted ``k`` grid steps later against ``ref`` (NaN if short)."""
    n = len(ref)
    a = ref[max(0, -k) : n - max(0, k)]
    b = sig[max(0, k) : n - max(0, -k)]
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    if ok.sum() < MIN_OVERLAP:
        return math.nan
    a0, b0 = a[ok] - a[ok].mean(axis=0), b[ok] - b[ok].mean(axis=0)
    den = math.sqrt(float((a0 * a0).sum()) * float((b0 * b0).sum()))
    return float((a0 * b0).sum()) / den if den > 0 else math.nan


def _coarse(ref: np.ndarray, sig: np.ndarray, kmax: int) -> np.ndarray:
    """Approximate correlations at lags -kmax..kmax by FFT (gaps as zeros, scaled by overlap)."""
    n = len(ref)
    ma = np.isfinite(ref).all(axis=1)
    mb = np.isfinite(sig).all(axis=1)
    a = np.where(ma[:, None], ref - np.nanmean(ref[ma], axis=0), 0.0) if ma.any() else ref * 0
    b = np.where(mb[:, None], sig - np.nanmean(sig[mb], axis=0), 0.0) if mb.any() else sig * 0
    size = 1 << (2 * n - 1).bit_length()

    def xcorr(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        c = np.fft.irfft(
            np.conj(np.fft.rfft(x, size, axis=0)) * np.fft.rfft(y, size, axis=0), size, axis=0
        )
        c = c.sum(axis=1) if c.ndim > 1 else c
        return np.concatenate([c[size - kmax :], c[: kmax + 1]])

    num = xcorr(a, b)
    overlap = xcorr(ma.astype(float), mb.astype(float))
    den = math.sqrt(float((a * a).sum()) * float((b * b).sum()))
    with np.errstate(divide="ignore", invalid="ignore"):
        out = num / den * (min(ma.sum(), mb.sum()) / overlap)
    out[overlap < max(MIN_OVERLAP, 0.5 * float(overlap.max()))] = np.nan
    return out


def best_lag(ref: np.ndarray, sig: np.ndarray, max_lag_s: float = MAX_LAG_S) -> Lag:
    """The lag (s) of ``sig`` behind ``ref`` that maximises their correlation, and that peak;
    the lag is None if unknown or if the peak is below MIN_CORR. The peak is found by FFT, then
    scored exactly with its neighbours (which refine it to a fraction of a grid step)."""
    n = len(ref)
    kmax = min(int(max_lag_s / GRID_S), n - MIN_OVERLAP)
    if kmax < 0 or den_zero(ref) or den_zero(sig):
        return None, None
    coarse = _coarse(ref, sig, kmax)
    if not np.isfinite(coarse).any():
        return None, None
    # scored exactly: the five best coarse lags with their neighbours, and every lag within
    # NEAR_S of zero (where latencies are; the FFT's gap handling is rough on sparse sources)
    top = np.argsort(np.nan_to_num(coarse, nan=-np.inf))[::-1][:5] - kmax
    ks = {k for k0 in top for k in range(max(-kmax, k0 - 2), min(kmax, k0 + 2) + 1)}
    near = min(kmax, int(NEAR_S / GRID_S))
    ks |= set(range(-near, near + 1))
    exact = {k: _score(ref, sig, k) for k in sorted(ks)}
    finite = {k: v for k, v in exact.items() if math.isfinite(v)}
    if not finite:
        return None, None
    k = max(finite, key=finite.__getitem__)
    peak = finite[k]
    if peak < MIN_CORR:
        return None, peak
    shift = 0.0
    lo, hi = exact.get(k - 1, math.nan), exact.get(k + 1, math.nan)  # neighbours are in ks
    if math.isfinite(lo) and math.isfinite(hi):
        d = lo - 2 * peak + hi
        shift = 0.5 * (lo - hi) / d if d < 0 else 0.0
    return (k + shift) * GRID_S, peak


def den_zero(x: np.ndarray) -> bool:
    """True when ``x`` has no finite row, or no variation (nothing to correlate)."""
    ok = np.isfinite(x).all(axis=1)
    return not ok.any() or float(np.ptp(x[ok], axis=0).max()) == 0.0


def difference(quantity: str, tr: Track, ref: Track) -> np.ndarray:
    """``tr`` minus ``ref`` at ``tr``'s readings (``ref`` interpolated; metres for positions)."""
    if len(ref.t) < 2 or len(tr.t) == 0:
        return np.zeros(0)
    if quantity == "position":
        lat0, lon0 = float(ref.v[0, 0]), float(ref.v[0, 1])
        a = _metres(tr.v[:, 0], tr.v[:, 1], lat0, lon0)
        b = _metres(ref.v[:, 0], ref.v[:, 1], lat0, lon0)
        bx, by = _on_grid(ref.t, b[:, 0], tr.t), _on_grid(ref.t, b[:, 1], tr.t)
        d = np.hypot(a[:, 0] - bx, a[:, 1] - by)
    elif quantity in ANGULAR:
        r = np.degrees(np.unwrap(np.radians(ref.v[:, 0])))
        d = (tr.v[:, 0] - _on_grid(ref.t, r, tr.t) + 180.0) % 360.0 - 180.0
    else:
        d = tr.v[:, 0] - _on_grid(ref.t, ref.v[:, 0], tr.t)
    return d[np.isfinite(d)]


def _course_rate(pos: Track, grid: np.ndarray) -> np.ndarray:
    """The rate of turn of the course over ground (deg/s) from positions, NaN when slow."""
    xy = _metres(pos.v[:, 0], pos.v[:, 1], float(pos.v[0, 0]), float(pos.v[0, 1]))
    vx = np.gradient(_on_grid(pos.t, xy[:, 0], grid), GRID_S)
    vy = np.gradient(_on_grid(pos.t, xy[:, 1], grid), GRID_S)
    cog = np.degrees(np.unwrap(np.arctan2(np.nan_to_num(vx), np.nan_to_num(vy))))
    rate = np.gradient(cog, GRID_S)
    rate[~(np.hypot(vx, vy) > MIN_SOG)] = np.nan
    return rate[:, None]


def _sog(pos: Track, grid: np.ndarray) -> np.ndarray:
    xy = _metres(pos.v[:, 0], pos.v[:, 1], float(pos.v[0, 0]), float(pos.v[0, 1]))
    vx = np.gradient(_on_grid(pos.t, xy[:, 0], grid), GRID_S)
    vy = np.gradient(_on_grid(pos.t, xy[:, 1], grid), GRID_S)
    s = np.hypot(vx, vy)
    return (s - np.nanmean(s))[:, None] if np.isfinite(s).any() else s[:, None]


def _origin(tr: Track) -> tuple[float, float]:
    """The first position of a position track (any other track: unused)."""
    return (float(tr.v[0, 0]), float(tr.v[0, 1])) if tr.v.shape[1] > 1 else (0.0, 0.0)


def _grid(*tracks: Track) -> np.ndarray:
    t0 = max(float(tr.t[0]) for tr in tracks)
    t1 = min(float(tr.t[-1]) for tr in tracks)
    if t1 - t0 < MIN_OVERLAP * GRID_S:
        return np.zeros(0)
    return np.arange(t0, t1, GRID_S)


def latency(quantity: str, tr: Track, pos: Track | None) -> Lag:
    """``tr``'s lag behind the position source (positions, headings, speed through water)."""
    if pos is None or len(pos.t) < 2 or len(tr.t) < 2:
        return None, None
    grid = _grid(tr, pos)
    if not len(grid):
        return None, None
    origin = _origin(pos)
    if quantity == "position":
        ref = signal("position", pos, grid, origin)
    elif quantity in ANGULAR:
        ref = _course_rate(pos, grid)
    elif quantity in ("stw", "velocity"):
        # accelerations: the current between them drifts slowly, their changes are the boat's
        ref = np.gradient(_sog(pos, grid), GRID_S, axis=0)
        sig = np.gradient(signal(quantity, tr, grid, origin), GRID_S, axis=0)
        return best_lag(ref, sig)
    else:
        return None, None
    return best_lag(ref, signal(quantity, tr, grid, origin))


def _stat(x: np.ndarray, fn: Any) -> float | None:
    return round(float(fn(x)), 3) if len(x) else None


def compare(
    quantity: str, tracks: dict[str, Track], chosen: str, position: Track | None, span_s: float
) -> dict[str, Any]:
    """Every source of ``quantity`` against ``chosen``, and each one's latency."""
    ref = tracks.get(chosen)
    out: dict[str, Any] = {"chosen": chosen, "unit": UNITS.get(quantity, ""), "sources": {}}
    for name, tr in tracks.items():
        row: dict[str, Any] = {
            "readings": tr.readings,
            "rate_hz": round(tr.rate_hz(), 3),
            "share": round(min(1.0, tr.covered_s() / span_s), 3) if span_s > 0 else None,
            "used": tr.used,
        }
        if ref is not None and name != chosen:
            d = difference(quantity, tr, ref)
            row["diff_median"] = _stat(d, np.median)
            row["diff_p95"] = _stat(np.abs(d), lambda x: np.percentile(x, 95))
            grid = _grid(tr, ref)
            lag, peak = None, None
            if len(grid):
                origin = _origin(ref)
                sig = signal(quantity, tr, grid, origin)
                lag, peak = best_lag(signal(quantity, ref, grid, origin), sig)
            row["lag_s"] = None if lag is None else round(lag, 2)
            row["lag_r"] = None if peak is None else round(peak, 2)
        lat, peak = latency(quantity, tr, position) if tr is not position else (0.0, 1.0)
        if lat is None and peak is not None:
            row["latency_note"] = f"no clear correlation peak (r = {peak:.2f})"
        if lat is not None and abs(lat) >= MAX_LAG_S - GRID_S:
            row["latency_note"] = f"at the edge of the search (+-{MAX_LAG_S:g} s): not a latency"
            lat = None
        row["latency_s"] = None if lat is None else round(lat, 2)
        out["sources"][name] = row
    return out


def analyse(
    tracks: dict[str, dict[str, Track]], chosen: dict[str, str], why: dict[str, str] | None = None
) -> dict[str, Any]:
    """Per quantity: ``compare`` of its sources, with why the chosen one was used."""
    times = [tr.t for q in tracks.values() for tr in q.values() if len(tr.t)]
    span = float(max(t[-1] for t in times) - min(t[0] for t in times)) if times else 0.0
    pos = tracks.get("position", {}).get(chosen.get("position", ""))
    out: dict[str, Any] = {}
    for q, srcs in tracks.items():
        if not srcs:
            continue
        c = chosen.get(q) or max(srcs, key=lambda n: (srcs[n].used, len(srcs[n].t)))
        out[q] = compare(q, srcs, c, pos, span)
        out[q]["why"] = (why or {}).get(q, "")
    return out


def sources_metadata(selector: Any) -> dict[str, str]:
    """The ``sources`` MCAP metadata record from a SourceSelector: one JSON text per quantity."""
    tracks = {
        q: {n: Track(n, tr.t, tr.v, tr.used, tr.n) for n, tr in srcs.items() if tr.t}
        for q, srcs in selector.tracks.items()
    }
    why = {q: selector.reason(q) for q in selector.tracks}
    result = analyse(tracks, {q: selector.chosen_track(q) for q in selector.chosen}, why)
    for q, s in selector.summary().items():
        if q in result:
            result[q]["switches"] = s["switches"]
            if "fix" in s:
                result[q]["fix"] = s["fix"]
    return {q: json.dumps(v, sort_keys=True) for q, v in result.items()}
