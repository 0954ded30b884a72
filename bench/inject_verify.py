"""How much of an injected effect a samples table recovered: 2-minute means against the truth's.

Two measures (``python bench/inject_nmea.py --verify``, and tests/test_injected_real.py):

- **alone**: the injected log's table against the truth, with an intercept: the real log's own
  current (leeway, the speed log's errors, a real tide) or seabed is the noise;
- **difference**: the injected table minus the clean one at the same rows (the same times: an
  injection moves no time), which isolates the injected part; what is left is what the pipeline did
  differently because of the effect (calibration, smoothing, rounding).

Rows are put in bins of ``BIN_S`` seconds from the log's start; a bin with fewer than ``MIN_ROWS``
rows that have the quantity is left out. The truth is interpolated at each row's time and averaged
over the same rows, so both means describe the same instants. Each fit is ordinary least squares
of the table's bin means on the truth's. Its slope's standard error comes from the residuals' own
correlation: successive bins of a real log's current are not independent (a leg sailed on one tack
keeps its leeway for many minutes), so the plain error is widened by sqrt((1 + rho) / (1 - rho)),
rho the residuals' lag-1 autocorrelation (the effective number of independent bins).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

BIN_S = 120.0
MIN_ROWS = 10


@dataclass(frozen=True)
class Fit:
    """A straight line through the bin means: table = intercept + slope * truth."""

    quantity: str
    how: str
    slope: float
    slope_se: float
    intercept: float
    r: float
    bins: int
    truth_sd: float
    rho: float = 0.0

    def line(self) -> str:
        return (
            f"{self.quantity:<14} {self.how:<10} slope {self.slope:6.3f} ± {self.slope_se:.3f}  "
            f"intercept {self.intercept:+.3f}  r {self.r:.3f}  bins {self.bins} "
            f"(rho {self.rho:+.2f})  truth sd {self.truth_sd:.3f}"
        )


def bin_means(t: np.ndarray, t0: float, *values: np.ndarray) -> list[np.ndarray]:
    """The mean of each of ``values`` per BIN_S bin over the rows where all are finite."""
    ok = np.isfinite(t)
    for v in values:
        ok &= np.isfinite(v)
    k = np.floor((t[ok] - t0) / BIN_S).astype(int)
    bins, inverse, counts = np.unique(k, return_inverse=True, return_counts=True)
    keep = counts >= MIN_ROWS
    out = []
    for v in values:
        sums = np.bincount(inverse, weights=v[ok], minlength=len(bins))
        out.append((sums / np.maximum(counts, 1))[keep])
    return out


def fit_line(quantity: str, how: str, table: np.ndarray, truth: np.ndarray) -> Fit:
    """Least squares of ``table`` on ``truth`` (bin means) with an intercept."""
    n = len(truth)
    if n < 3 or np.std(truth) == 0:
        return Fit(quantity, how, math.nan, math.nan, math.nan, math.nan, n, float(np.std(truth)))
    x = truth - truth.mean()
    slope = float(np.dot(x, table - table.mean()) / np.dot(x, x))
    intercept = float(table.mean() - slope * truth.mean())
    resid = table - intercept - slope * truth
    se = float(np.sqrt(np.dot(resid, resid) / max(n - 2, 1) / np.dot(x, x)))
    rho = lag1(resid)
    se *= math.sqrt((1.0 + max(rho, 0.0)) / (1.0 - min(max(rho, 0.0), 0.95)))
    r = float(np.corrcoef(truth, table)[0, 1])
    return Fit(quantity, how, slope, se, intercept, r, n, float(np.std(truth)), rho)


def lag1(v: np.ndarray) -> float:
    """The lag-1 autocorrelation of a series (0 for a constant one)."""
    d = v - v.mean()
    den = float(np.dot(d, d))
    return 0.0 if den == 0 else float(np.dot(d[1:], d[:-1]) / den)


def truth_at(truth: dict[str, np.ndarray], column: str, t: np.ndarray) -> np.ndarray:
    """The truth's ``column`` at times ``t`` (NaN outside the log)."""
    return np.interp(t, truth["t"], truth[column], left=np.nan, right=np.nan)


@dataclass(frozen=True)
class LevelMatch:
    """A fitted water level against an injected one, both centred: their correlation, the fitted level's
    slope on the truth, and the share of rows where the truth lies within the level's own 2 sd."""

    r: float
    slope: float
    inside: float

    def line(self) -> str:
        return f"r {self.r:.3f}, slope {self.slope:.2f}, {self.inside:.0%} of rows within 2 sd"


def level_match(sm, survey, truth) -> LevelMatch:  # type: ignore[no-untyped-def]
    """The level of a fitted depth model `sm` (`water_level.level_estimate`) on `survey`'s rows against
    the truth's `level` column (a table with `t` and `level`, times as the survey's)."""
    from forcemap.host.workbench.depth.water_level import level_estimate

    est, sd = level_estimate(sm.primary, survey.trel)
    level = np.interp(survey.columns["t"], np.asarray(truth["t"]), np.asarray(truth["level"]))
    est, level = est - est.mean(), level - level.mean()
    return LevelMatch(
        r=float(np.corrcoef(est, level)[0, 1]),
        slope=float(np.dot(level, est) / np.dot(level, level)),
        inside=float(np.mean(np.abs(est - level) <= 2 * sd)),
    )


def along(cols: dict[str, np.ndarray], unit: tuple[float, float], prefix: str) -> np.ndarray:
    return cols[prefix + "_east"] * unit[0] + cols[prefix + "_north"] * unit[1]


def _matched(
    table: dict[str, np.ndarray], clean: dict[str, np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the rows both tables have (the same time, to a microsecond)."""
    a = np.round(table["t"] * 1e6).astype(np.int64)
    b = np.round(clean["t"] * 1e6).astype(np.int64)
    _, ia, ib = np.intersect1d(a, b, return_indices=True)
    return ia, ib


def recovery(
    table: dict[str, np.ndarray],
    truth: dict[str, np.ndarray],
    clean: dict[str, np.ndarray] | None = None,
    toward_deg: float | None = None,
) -> list[Fit]:
    """The fits of current (east, north and along ``toward_deg``) and depth, alone and, with a
    ``clean`` table, as a difference; only the quantities the truth varies."""
    t0 = float(truth["t"][0])
    t = table["t"]
    tcols = {
        "current_east": truth_at(truth, "current_east", t),
        "current_north": truth_at(truth, "current_north", t),
        "depth": truth_at(truth, "level", t),
    }
    names = ["current_east", "current_north", "depth"]
    if toward_deg is not None:
        u = (math.sin(math.radians(toward_deg)), math.cos(math.radians(toward_deg)))
        tcols["current_along"] = tcols["current_east"] * u[0] + tcols["current_north"] * u[1]
        table = dict(table, current_along=along(table, u, "current"))
        if clean is not None:
            clean = dict(clean, current_along=along(clean, u, "current"))
        names.append("current_along")
    fits = []
    for name in names:
        if np.nanstd(tcols[name]) < 1e-9 or name not in table:
            continue
        y, x = bin_means(t, t0, table[name], tcols[name])
        fits.append(fit_line(name, "alone", y, x))
        if clean is not None:
            ia, ib = _matched(table, clean)
            diff = table[name][ia] - clean[name][ib]
            y, x = bin_means(t[ia], t0, diff, tcols[name][ia])
            fits.append(fit_line(name, "difference", y, x))
    return fits


def read_table(path: str) -> dict[str, np.ndarray]:
    """A samples table (CSV or Parquet) as float columns (empty cells NaN)."""
    if str(path).lower().endswith((".parquet", ".pq")):
        import pyarrow.parquet as pq

        tab = pq.read_table(path)
        return {
            c: np.array([np.nan if v is None else v for v in tab.column(c).to_pylist()], float)
            for c in tab.column_names
            if c == "t" or tab.schema.field(c).type != "string"
        }
    import csv

    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    out = {}
    for j, c in enumerate(head):
        try:
            out[c] = np.array([float(r[j]) if r[j] != "" else np.nan for r in body])
        except ValueError:
            continue
    return out
