"""How long a map stays true: every survey's own current map predicts every later survey, scored from the later
survey's sufficient statistics (no second pass over the data). The error is fitted as a straight line in the
map's age d, e(d) = e0 + a d; the age at which it doubles is e0 / a ("maps here lose half their skill in
e0 / a days"). The same errors against the change in the discharge scale show why."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from forcemap.host.season.stats import Stats
from forcemap.host.workbench.errors import WorkbenchError

DAY_S = 86400.0


@dataclass
class Staleness:
    """Pairs (earlier i, later j): age in days, |s_j - s_i|, vector RMSE of i's map on j (m/s)."""

    i: np.ndarray
    j: np.ndarray
    age_days: np.ndarray
    dscale: np.ndarray
    rmse: np.ndarray
    e0: float  # fitted error of a fresh map (age 0), m/s
    per_day: float  # growth per day of age, m/s
    per_dscale: float  # growth per unit change of the scale, m/s
    doubling_days: float | None  # None: the error does not grow with age

    def to_json(self) -> dict:
        return {
            "pairs": len(self.i),
            "fresh_map_rmse_mps": self.e0,
            "rmse_growth_mps_per_day": self.per_day,
            "rmse_growth_mps_per_unit_scale_change": self.per_dscale,
            "doubling_age_days": self.doubling_days,
            "age_days": self.age_days.tolist(),
            "scale_change": self.dscale.tolist(),
            "rmse_mps": self.rmse.tolist(),
            "earlier": self.i.tolist(),
            "later": self.j.tolist(),
        }


def _line(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    if len(x) < 2 or np.ptp(x) == 0:
        return float(np.mean(y)) if len(y) else float("nan"), 0.0
    slope, icept = np.polyfit(x, y, 1)
    return float(icept), float(slope)


def staleness(
    t_mid: np.ndarray, scales: np.ndarray, own_maps: list[np.ndarray], stats: list[Stats]
) -> Staleness:
    """`own_maps[k]`: survey k's own current weights (m x 2); `stats[k]`: its current statistics."""
    order = np.argsort(t_mid, kind="stable")
    sq = _pair_sq_errors([own_maps[i] for i in order], [stats[j] for j in order])
    rows = []
    for a, i in enumerate(order):
        for b in range(a + 1, len(order)):
            j, st = order[b], stats[order[b]]
            err = (max(sq[a, b], 0.0) / max(st.n, 1)) ** 0.5
            rows.append((i, j, (t_mid[j] - t_mid[i]) / DAY_S, abs(scales[j] - scales[i]), err))
    arr = np.array(rows, float).reshape(-1, 5)
    age, ds, rmse = arr[:, 2], arr[:, 3], arr[:, 4]
    e0, per_day = _line(age, rmse)
    _, per_ds = _line(ds, rmse)
    doubling = e0 / per_day if per_day > 0 and e0 > 0 else None
    return Staleness(
        arr[:, 0].astype(int), arr[:, 1].astype(int), age, ds, rmse, e0, per_day, per_ds, doubling
    )


def _pair_sq_errors(maps: list[np.ndarray], stats: list[Stats]) -> np.ndarray:
    """sq[a, b] = `sq_error(stats[b], maps[a])` for every a < b (the rest is not computed): per later survey b
    one product of its Gram matrix with every earlier map at once, O(K^2 m^2) in K matrix products rather
    than K^2 / 2 matrix-vector products."""
    K = len(maps)
    sq = np.zeros((K, K))
    if K < 2:
        return sq
    m, k = maps[0].shape
    W = np.stack(maps, axis=1).reshape(m, K * k)  # column a * k + c: map a, target column c
    for b in range(1, K):
        st, Wa = stats[b], W[:, : b * k]
        quad = (Wa * (st.G @ Wa)).sum(axis=0).reshape(b, k).sum(axis=1)
        cross = (Wa * np.tile(st.B, b)).sum(axis=0).reshape(b, k).sum(axis=1)
        sq[:b, b] = np.trace(st.R) - 2.0 * cross + quad
    return sq


def binned(x: np.ndarray, y: np.ndarray, bins: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Mean of y in equal-width bins of x (the curve the plots draw over the pairs)."""
    if len(x) == 0:
        return np.zeros(0), np.zeros(0)
    edges = np.linspace(x.min(), x.max() + 1e-12, bins + 1)
    k = np.clip(np.digitize(x, edges) - 1, 0, bins - 1)
    keep = np.bincount(k, minlength=bins) > 0
    mean = np.bincount(k, weights=y, minlength=bins)[keep] / np.bincount(k, minlength=bins)[keep]
    return (0.5 * (edges[:-1] + edges[1:]))[keep], mean


def plan_note(season_dir: str | Path, map_time: float, at: float) -> str:
    """The line `forcemap plan --season` prints: the map's age at `at` (UNIX s) and the season's doubling age."""
    path = Path(season_dir) / "season.json"
    try:
        st = json.loads(path.read_text())["staleness"]
    except (OSError, ValueError, KeyError, TypeError):
        raise WorkbenchError(
            f"{path} is not a season with a staleness curve; make one with `forcemap season`"
        ) from None
    return message(max(at - map_time, 0.0) / DAY_S, st["doubling_age_days"])


def message(age_days: float, doubling_days: float | None) -> str:
    """What `forcemap plan` says about its map's age."""
    if doubling_days is None:
        return f"this map is {age_days:.0f} days old; in this season a map's error did not grow with its age"
    return (
        f"this map is {age_days:.0f} days old; maps here lose half their skill in "
        f"{doubling_days:.0f} days (their error doubles)"
    )
