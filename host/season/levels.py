"""The season's water levels: each survey's level (from the depth model, `model.fit_depth`) against the
current's scale (the discharge), the rating-curve check that says when the two disagree, and its figure.

A river's stage rises with its discharge as a power law (a USGS stage-discharge rating, Q = C (h - e)^b),
so the levels should rise monotonically with the current's per-survey scale. When they do not (a rank
correlation below RANK_MIN), or one survey sits far off the fitted curve, the check says so: a gauge datum
shift, a change of the channel's control (a moved bar, weed), a backwater from downstream, or a current
scale that is not the discharge (wind drift)."""

from __future__ import annotations

import numpy as np
from scipy import stats

# the levels follow the scales when their rank correlation is at least this (with MIN_SURVEYS or more)
RANK_MIN = 0.6
MIN_SURVEYS = 4
# a survey is off the rating when its level is this many of its combined sds from the fitted curve
OFF_SD = 4.0
MIN_SPREAD_M = 0.03


def survey_levels(season) -> dict[str, tuple[float, float]]:
    """path -> (level, sd) in m, centred on the season's mean; empty without per-survey levels."""
    d = season.depth
    if d is None or d.levels is None:
        return {}
    return {p: (float(v), float(s)) for p, v, s in zip(d.paths, d.levels, d.level_sd, strict=True)}


def rating_check(season) -> dict | None:
    """Levels against the current's scales (the surveys that have both): the rank correlation, a fitted
    rating level = a + c log(scale), its residual spread, the surveys off it and a one-line verdict."""
    lv = survey_levels(season)
    cur = season.current
    if not lv or cur is None:
        return None
    cur_paths = [s.path for s in season.surveys if s.has["current_east"] and s.has["current_north"]]
    scale = dict(zip(cur_paths, cur.scales.tolist(), strict=True))
    both = [p for p in lv if p in scale and scale[p] > 0]
    if len(both) < 3:
        return None
    q = np.log([scale[p] for p in both])
    h = np.array([lv[p][0] for p in both])
    sd = np.array([lv[p][1] for p in both])
    A = np.column_stack([np.ones_like(q), q])
    coef, *_ = np.linalg.lstsq(A, h, rcond=None)
    resid = h - A @ coef
    spread = float(np.sqrt(np.sum(resid**2) / max(len(h) - 2, 1)))
    rho = float(stats.spearmanr(q, h).statistic) if np.ptp(q) > 0 and np.ptp(h) > 0 else 0.0
    off = [both[k] for k in _off_curve(A, h, sd)]
    agree = (len(both) < MIN_SURVEYS or rho >= RANK_MIN) and not off
    if agree:
        verdict = (
            f"the stage follows the current's scale (rank correlation {rho:.2f}; off a rating curve by "
            f"{spread:.3f} m rms)"
        )
    else:
        why = f"rank correlation {rho:.2f}" + (f"; off the curve: {', '.join(off)}" if off else "")
        verdict = (
            f"the stage and the current's scale disagree ({why}): a gauge datum shift, a changed control "
            "(a moved bar, weed), a backwater, or a current scale that is not the discharge"
        )
    return {
        "surveys": len(both),
        "rank_correlation": rho,
        "slope_m_per_log_scale": float(coef[1]),
        "rms_off_curve_m": spread,
        "off_curve": off,
        "agree": bool(agree),
        "verdict": verdict,
        "points": [[scale[p], lv[p][0], lv[p][1]] for p in both],
        "curve": coef.tolist(),
    }


def _off_curve(A: np.ndarray, h: np.ndarray, sd: np.ndarray) -> list[int]:
    """The surveys whose level is off the curve fitted to the others by more than OFF_SD of its sd and the
    others' spread about their curve (at least MIN_SPREAD_M: a power law is not quite a line in log Q)."""
    if len(h) < MIN_SURVEYS:
        return []
    out = []
    for k in range(len(h)):
        rest = np.arange(len(h)) != k
        coef, *_ = np.linalg.lstsq(A[rest], h[rest], rcond=None)
        r = h[rest] - A[rest] @ coef
        spread = max(float(np.sqrt(np.sum(r**2) / max(rest.sum() - 2, 1))), MIN_SPREAD_M)
        if abs(h[k] - A[k] @ coef) > OFF_SD * float(np.hypot(sd[k], spread)):
            out.append(k)
    return out


def rating_figure(check: dict):
    """Stage against the current's scale, with the fitted rating curve."""
    from forcemap.host.workbench.fits.plots import new_figure

    pts = np.array(check["points"])
    fig = new_figure((6, 3.6))
    ax = fig.add_subplot(111)
    ax.errorbar(pts[:, 0], pts[:, 1], yerr=2 * pts[:, 2], fmt="o", capsize=2)
    s = np.linspace(pts[:, 0].min(), pts[:, 0].max(), 50)
    a, c = check["curve"]
    ax.plot(s, a + c * np.log(s), "r-", lw=1)
    ax.set_xlabel("current scale (discharge, 1 = season mean)")
    ax.set_ylabel("water level (m, season mean 0)")
    ax.set_title("rating curve: stage against discharge")
    return fig
