"""A period in an unevenly sampled series: the generalised Lomb-Scargle periodogram (floating mean, weights;
Zechmeister & Kuerster 2009), the peak refined by the profile likelihood of a sinusoid, the period's sd from
that likelihood's curvature with the effective sample size of the residuals' own autocorrelation, and
Baluev's (2008) false-alarm probability. `estimate_period(t, y)` is what diagnose calls on a residual."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.special import gammaln

# a seiche shorter than this is hard to tell from the map along a survey line (the boat passes a 100 m
# feature in half a minute, a line in minutes): the default search starts here
MIN_PERIOD_S = 600.0
# at least this many cycles in the record
MIN_CYCLES = 1.5
OVERSAMPLE = 10
MAX_FREQS = 20_000


class PeriodEstimate(NamedTuple):
    """A period (s), its sd (s), the periodogram's peak power (the share of the variance a sinusoid at
    that period explains, 0-1) and the probability that noise alone gives a peak this high."""

    period_s: float
    period_sd_s: float
    power: float
    fap: float


def search_range(t: np.ndarray, p_min: float | None, p_max: float | None) -> tuple[float, float]:
    """(shortest, longest) period searched: MIN_PERIOD_S (or 4 sample spacings) to the span / MIN_CYCLES."""
    span = float(np.ptp(t))
    dt = float(np.median(np.diff(np.sort(t)))) if len(t) > 1 else 1.0
    lo = p_min if p_min is not None else max(MIN_PERIOD_S, 4.0 * dt)
    hi = p_max if p_max is not None else span / MIN_CYCLES
    if not (0 < lo < hi):
        raise ValueError(
            f"no period to search: the record spans {span:.0f} s, too short for {MIN_CYCLES:g} "
            f"cycles of a period of at least {lo:.0f} s"
        )
    return lo, hi


def chi2(t: np.ndarray, Y: np.ndarray, w: np.ndarray, freqs: np.ndarray) -> np.ndarray:
    """Weighted residual sum of squares of `mean + a cos + b sin` at each frequency (Hz), summed over the
    columns of Y (n, c): the generalised Lomb-Scargle fit, in closed form, in chunks of frequencies."""
    w = w / w.sum()
    Y = Y - w @ Y
    out = np.empty(len(freqs))
    chunk = max(1, 4_000_000 // max(len(t), 1))
    for a in range(0, len(freqs), chunk):
        f = freqs[a : a + chunk]
        arg = 2 * np.pi * np.outer(f, t)
        c, s = np.cos(arg), np.sin(arg)
        C, S = c @ w, s @ w
        CC = (c * c) @ w - C * C
        SS = (s * s) @ w - S * S
        CS = (c * s) @ w - C * S
        YC, YS = (c * w) @ Y, (s * w) @ Y  # (F, c)
        D = np.maximum(CC * SS - CS * CS, 1e-300)
        explained = (SS[:, None] * YC**2 + CC[:, None] * YS**2 - 2 * CS[:, None] * YC * YS) / D[
            :, None
        ]
        out[a : a + len(f)] = float((w @ Y**2).sum()) - explained.sum(axis=1)
    return np.maximum(out, 1e-300)


def effective_n(t: np.ndarray, r: np.ndarray) -> float:
    """Samples worth of independent information in residuals `r`: n (1 - rho) / (1 + rho) for their lag-one
    autocorrelation rho (an AR(1) reading of their own correlation)."""
    order = np.argsort(t)
    x = r[order] - r.mean()
    rho = float(x[1:] @ x[:-1] / max(x @ x, 1e-300)) if len(x) > 2 else 0.0
    rho = min(max(rho, 0.0), 0.999)
    return max(3.0, len(r) * (1 - rho) / (1 + rho))


def fap_baluev(z: float, n: float, f_max: float, t: np.ndarray) -> float:
    """Baluev's (2008) false-alarm probability of a peak of standard power `z` searched up to `f_max` Hz,
    with `n` independent samples."""
    if z <= 0:
        return 1.0
    nh, nk = n - 1, n - 3
    single = (1 - z) ** (0.5 * nk)
    gamma = math.sqrt(2 / nh) * math.exp(gammaln(nh / 2) - gammaln((nh - 1) / 2))
    w = f_max * math.sqrt(4 * math.pi * float(np.var(t)))
    tau = gamma * w * (1 - z) ** (0.5 * (nk - 1)) * math.sqrt(0.5 * nh * z)
    return float(min(1.0, max(0.0, 1 - (1 - single) * math.exp(-tau))))


def curvature_sd(x: np.ndarray, loglik: np.ndarray) -> float:
    """sd of x from a parabola through the log-likelihood's points within 2 nats of its maximum."""
    i = int(np.argmax(loglik))
    near = loglik >= loglik[i] - 2.0
    lo, hi = i, i
    while lo > 0 and near[lo - 1]:
        lo -= 1
    while hi + 1 < len(x) and near[hi + 1]:
        hi += 1
    lo, hi = max(0, min(lo, i - 1)), min(len(x) - 1, max(hi, i + 1))
    a = np.polyfit(x[lo : hi + 1] - x[i], loglik[lo : hi + 1], 2)[0]
    return math.sqrt(-0.5 / a) if a < 0 else float(x[-1] - x[0])


def frequencies(t: np.ndarray, p_min: float, p_max: float) -> np.ndarray:
    span = float(np.ptp(t))
    n = int(min(MAX_FREQS, max(50, math.ceil(OVERSAMPLE * (1 / p_min - 1 / p_max) * span))))
    return np.linspace(1 / p_max, 1 / p_min, n)


def estimate_period(
    t: np.ndarray,
    y: np.ndarray,
    weights: np.ndarray | None = None,
    p_min: float | None = None,
    p_max: float | None = None,
) -> PeriodEstimate:
    """The dominant period of `y` (one series, or the columns of an (n, c) array together) at times `t` (s).

    The periodogram's peak is refined on a fine grid by the profile likelihood of a sinusoid plus a mean
    (the noise variance maximised out: `-n_eff/2 log chi2`), and the period's sd comes from its curvature,
    with n_eff the effective sample size of the residuals (their lag-one autocorrelation): samples 0.25 s
    apart along a track are not independent, and counted as if they were the sd would be far too small."""
    t = np.asarray(t, float)
    Y = np.asarray(y, float).reshape(len(t), -1)
    w = np.ones(len(t)) if weights is None else np.asarray(weights, float)
    ok = np.isfinite(t) & np.isfinite(Y).all(axis=1) & np.isfinite(w) & (w > 0)
    t, Y, w = t[ok], Y[ok], w[ok]
    if len(t) < 10:
        raise ValueError(f"too few samples ({len(t)}) to estimate a period")
    lo, hi = search_range(t, p_min, p_max)
    freqs = frequencies(t, lo, hi)
    c2 = chi2(t, Y, w, freqs)
    wn = w / w.sum()
    c0 = float((wn @ (Y - wn @ Y) ** 2).sum())
    k = int(np.argmin(c2))
    step = freqs[1] - freqs[0]
    fine = np.linspace(freqs[k] - 2 * step, freqs[k] + 2 * step, 41)
    fine = fine[fine > 0]
    c2f = chi2(t, Y, w, fine)
    best = float(fine[int(np.argmin(c2f))])
    resid = _sinusoid_residual(t, Y, w, best)
    n_eff = effective_n(t, resid)
    span = float(np.ptp(t))
    wide = np.linspace(best - 1.5 / span, best + 1.5 / span, 121)
    wide = wide[wide > 0]
    loglik = -0.5 * n_eff * np.log(chi2(t, Y, w, wide))
    sd_f = curvature_sd(wide, loglik)
    z = 1.0 - float(c2f.min()) / c0 if c0 > 0 else 0.0
    return PeriodEstimate(1.0 / best, sd_f / best**2, z, fap_baluev(z, n_eff, 1 / lo, t))


def _sinusoid_residual(t: np.ndarray, Y: np.ndarray, w: np.ndarray, f: float) -> np.ndarray:
    """The residual of the weighted least-squares mean and sinusoid at `f` (first column)."""
    A = np.column_stack([np.ones_like(t), np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)])
    sw = np.sqrt(w)
    coef = np.linalg.lstsq(A * sw[:, None], Y[:, 0] * sw, rcond=None)[0]
    return Y[:, 0] - A @ coef
