"""The `reference_stream` effect: a tidal stream that is a reference station's prediction, times a known
ratio and later by a known offset, both varying across the survey (a subordinate station everywhere).

The station is one of the NOAA stations forcemap ships (host/data/noaa_sfbay_currents.json), its
prediction r(t) along its flood axis from its harmonic constants (host/vessel/reference_current.py), so
the stream carries the station's spring and neap and its diurnal inequality, day after day. At a place
x east of the scenario's origin (xi = (x - the survey box's centre) / half its width, -1 to 1):

    ratio(x) = ratio + ratio_east xi,   offset(x) = offset_min + offset_east_min xi   (minutes)
    stream(x, t) = ratio(x) r(t - offset(x))

along the channel (a river) or the flow direction (a lake), added to the river's own current times
`river`. `truth(x)` gives both fields for a test to compare with what a fit recovers.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
from forcemap.host.vessel.reference_current import ReferenceCurrent, Station, read_reference

REFERENCE = Path(__file__).resolve().parents[1] / "host" / "data" / "noaa_sfbay_currents.json"
TABLE_STEP_S = 10.0


@cache
def shipped() -> ReferenceCurrent:
    """The stations forcemap ships (NOAA's central San Francisco Bay)."""
    return read_reference(REFERENCE)


class ReferenceStream:
    """The stream of one run: a station's prediction on a table every TABLE_STEP_S, read at each place's
    own time (the run's time less its offset)."""

    def __init__(self, params: dict, t0: float, centre_x: float, half_span_x: float) -> None:
        self.p = params
        self.t0 = float(t0)
        self.centre, self.half = float(centre_x), max(float(half_span_x), 1.0)
        self.station: Station = shipped().stations[shipped().choose(str(params["station"])).chosen]
        self._tables: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def truth(self, x) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
        """(ratio, offset in s) at east positions `x` (m)."""
        xi = np.clip((np.asarray(x, float) - self.centre) / self.half, -1.0, 1.0)
        ratio = self.p["ratio"] + self.p["ratio_east"] * xi
        offset = 60.0 * (self.p["offset_min"] + self.p["offset_east_min"] * xi)
        return ratio, offset

    def _table(self, hour: int) -> tuple[np.ndarray, np.ndarray]:
        """The hour's grid of UNIX times (every TABLE_STEP_S, both ends) and the station's prediction on it."""
        got = self._tables.get(hour)
        if got is None:
            grid = 3600.0 * hour + np.arange(0.0, 3600.0 + TABLE_STEP_S + 1e-9, TABLE_STEP_S)
            got = self._tables[hour] = (grid, self.station.speed(grid))
        return got

    def _r(self, unix: np.ndarray) -> np.ndarray:
        """The station's prediction at UNIX times, read from hour-long tables."""
        out = np.empty(unix.shape)
        hours = np.floor(unix / 3600.0).astype(np.int64)
        for h in np.unique(hours):
            grid, table = self._table(int(h))
            m = hours == h
            out[m] = np.interp(unix[m], grid, table)
        return out

    def __call__(self, x, t):  # type: ignore[no-untyped-def]
        """The stream (m/s, positive with the flow) at east positions `x` and run times `t`."""
        if np.ndim(x) == 0 and np.ndim(t) == 0:
            return self._at(float(x), float(t))
        xa, ta = np.broadcast_arrays(np.asarray(x, float), np.asarray(t, float))
        ratio, offset = self.truth(xa)
        unix = self.t0 + ta - offset
        out = ratio * self._r(unix.ravel()).reshape(unix.shape)
        return float(out) if not np.ndim(out) else out

    def _at(self, x: float, t: float) -> float:
        """`__call__` at one place and time (the boat loop's every step), with the same arithmetic
        without numpy's array machinery: the same numbers, bit for bit."""
        xi = min(max((x - self.centre) / self.half, -1.0), 1.0)
        ratio = self.p["ratio"] + self.p["ratio_east"] * xi
        offset = 60.0 * (self.p["offset_min"] + self.p["offset_east_min"] * xi)
        unix = self.t0 + t - offset
        grid, table = self._table(int(np.floor(unix / 3600.0)))
        return float(ratio * np.interp(unix, grid, table))
