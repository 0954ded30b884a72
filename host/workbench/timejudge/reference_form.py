"""A reference station's predicted current as one more form a change in time can take (`--reference-current`).

Where a station's prediction is given, a tidal current is a change that follows it: at each place, a ratio
of the station's current and a time offset (a subordinate station, `tide(reference)`). Linearised in the
offset (terms/reference_tide.py), ratio x R(t - offset) = a R(t) + b R'(t) / w, so at the revisits the form
is two columns, the prediction R and its rate R' (over the M2 frequency, in the same unit), differenced over
each pair as the ladder's cosine and sine are. Each vector component has its own coefficients: the place's
own flood axis. The form is judged beside the ladder's with the same null (whole stretches exchanging their
times, the prediction moving with them) and the same max-statistic, so it costs no false findings and is
named only where it explains more than a drift or a period of the ladder.
"""

from __future__ import annotations

import numpy as np
from forcemap.host.workbench.terms.reference_tide import OMEGA, relation
from forcemap.host.workbench.timejudge.forms import Projector, pair_shares
from forcemap.host.workbench.timejudge.revisits import RevisitPairs

# the prediction is tabulated at this step (s) over the judged span and interpolated linearly: a
# semidiurnal tide's error there is below 1e-5 of its amplitude
GRID_S = 60.0


class ReferenceForm:
    """The station prediction (and its rate) at each judged row's place, at any time within the judged span,
    and the form's columns at the revisit pairs for their own times or their stretches' exchanged ones."""

    def __init__(self, reference, lat: np.ndarray, lon: np.ndarray, utc0: float, rp: RevisitPairs):
        """`lat`, `lon`: the judged rows' places; `utc0`: the UNIX time of `rp.t` = 0."""
        self.rp = rp
        station = reference.station_index(lat, lon)
        used, self.row_station = np.unique(station, return_inverse=True)
        end = rp.n_stretches * rp.stretch_s + float(np.ptp(rp.t)) + 2 * GRID_S
        self.grid = np.arange(-GRID_S, end, GRID_S)
        stations = [reference.stations[reference.ids[i]] for i in used]
        utc = utc0 + self.grid
        self.speed = np.nan_to_num(np.array([s.speed(utc) for s in stations]))
        self.rate = np.nan_to_num(np.array([s.rate(utc) for s in stations])) / OMEGA
        top = int(np.argmax(np.bincount(self.row_station)))
        self.station = stations[top]  # the most used
        self._top_row = int(np.flatnonzero(self.row_station == top)[0])

    def _at(self, table: np.ndarray, rows: np.ndarray, t: np.ndarray) -> np.ndarray:
        """`table`'s value at each row's station and time t (s since the judged start)."""
        pos = np.clip((t - self.grid[0]) / GRID_S, 0.0, len(self.grid) - 1.000001)
        i = pos.astype(int)
        f = pos - i
        st = self.row_station[rows]
        return table[st, i] * (1.0 - f) + table[st, i + 1] * f

    def columns(
        self, ta: np.ndarray, tb: np.ndarray, proj: Projector
    ) -> tuple[np.ndarray, np.ndarray]:
        """The prediction's and its rate's columns, differenced over each pair (the pairs' times `ta`,
        `tb`), the nuisance taken out."""
        a, b = self.rp.pairs[:, 0], self.rp.pairs[:, 1]
        C = self._at(self.speed, b, tb) - self._at(self.speed, a, ta)
        S = self._at(self.rate, b, tb) - self._at(self.rate, a, ta)
        return proj(C[:, None]), proj(S[:, None])

    def share(self, d: np.ndarray, ta, tb, proj: Projector) -> float:
        """The share of the differences' sum of squares the form explains."""
        return float(pair_shares(d, *self.columns(ta, tb, proj))[0])

    def null(self, d: np.ndarray, orders: np.ndarray, proj: Projector) -> np.ndarray:
        """The form's share for each permutation of the stretches (a row of `orders`)."""
        return np.array([self.share(d, *self.rp.times(order), proj) for order in orders])

    def basis(self, t: np.ndarray) -> np.ndarray:
        """The form's functions of time (s since the judged start), undifferenced, at the most used station."""
        rows = np.full(len(t), self._top_row)
        return np.column_stack([self._at(self.speed, rows, t), self._at(self.rate, rows, t)])


def ratio_and_offset(w: np.ndarray) -> tuple[float, float]:
    """The ratio to the station and the time offset (s, the place later than the station by it) that the
    form's coefficients `w` (2 x components) give; a vector's along the axis its coefficients on the
    prediction point."""
    a, b = np.atleast_1d(w[0]), np.atleast_1d(w[1])
    along = float(np.sqrt((a * a).sum()))
    if along <= 0:
        return 0.0, 0.0
    return relation(along, float((a * b).sum()) / along)
