"""The maps the replanner asks for after each line: the live map's latest grids, or a refit.

- ``BoardMaps``: with `forcemap run --live`, the live map process's newest current and wind grids
  (host/live/mapproc.py ``MapBoard``), moved into the replanner's frame;
- ``RefitMaps``: without it, the ``/samples`` rows the pipeline writes are kept (every
  ``SPACING_S``), and each call fits the workbench's baseline model (BASELINE terms, or the terms given:
  `run --replan-terms tide`) to the east and north components of current and wind and grids it over the
  mission's area, exactly as `forcemap plan` maps a finished survey; a field with a term in time (a tide)
  is gridded at times over the next REST_S from the newest sample, so that the rest of the mission is
  planned in the current expected when the boat is on each line.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.survey.table import Survey
from forcemap.host.workbench.terms.spec import BASELINE

from .inflight import MapSnapshot
from .maps import Field, Maps, field_times, fit_field

SPACING_S = 0.5  # keep one sample every this many seconds (the pipeline writes 10 per second)
MIN_SAMPLES = 60
COLUMNS = ("t", "lat", "lon", "current_east", "current_north", "wind_east", "wind_north")
REST_S = 3 * 3600.0  # a field in time is gridded this far ahead of the newest sample


class RefitMaps:
    """A MapProvider: ``add`` each /samples row; calling it fits the maps on the rows so far."""

    def __init__(
        self,
        lat0: float,
        lon0: float,
        bounds: tuple[float, float, float, float],
        terms: list[str] | None = None,
    ) -> None:
        self.lat0, self.lon0, self.bounds = lat0, lon0, bounds
        self.terms = list(terms or BASELINE)
        self.rows: list[tuple[float, ...]] = []
        self._last_t = -np.inf
        self._lock = threading.Lock()  # rows come from the daemon's thread, fits run in another

    def add(self, row: dict) -> None:
        t = row.get("t")
        if t is None or t < self._last_t + SPACING_S:
            return
        vals = tuple(np.nan if row.get(c) is None else float(row[c]) for c in COLUMNS)
        if np.isfinite(vals[1]) and np.isfinite(vals[2]):
            with self._lock:
                self.rows.append(vals)
            self._last_t = t

    def survey(self) -> Survey | None:
        with self._lock:
            a = np.array(self.rows)
        ok = np.isfinite(a[:, 3]) & np.isfinite(a[:, 4]) if len(a) else np.zeros(0, bool)
        if ok.sum() < MIN_SAMPLES:
            return None
        cols = {c: a[:, i] for i, c in enumerate(COLUMNS)}
        cols["x"], cols["y"] = LocalFrame(self.lat0, self.lon0).to_local(cols["lat"], cols["lon"])
        return Survey(cols, self.lat0, self.lon0, float(cols["t"][0]), Path("live"))

    def __call__(self) -> MapSnapshot | None:
        sv = self.survey()
        if sv is None:
            return None
        fields = {}
        newest = float(sv.columns["t"][-1])
        times = field_times(self.terms, newest, REST_S)
        for prefix in ("current", "wind"):
            e = sv.columns[f"{prefix}_east"]
            if np.isfinite(e).sum() < MIN_SAMPLES:
                fields[prefix] = Field.still()
                continue
            terms = self.terms if prefix == "current" else list(BASELINE)
            at = times if prefix == "current" else None
            fields[prefix] = fit_field(sv, prefix, terms, self.bounds, cv=False, times=at)
        maps = Maps(fields["current"], fields["wind"], self.lat0, self.lon0, start=newest)
        return MapSnapshot(maps, float(sv.columns["t"][-1]), sv.n)


def moved(f: Field, dx: float, dy: float) -> Field:
    """A field on a grid whose origin is (dx, dy) m from the frame it is wanted in."""
    return Field(
        f.x0 + dx, f.y0 + dy, f.step, f.east, f.north, f.east_sd, f.north_sd, f.terms, f.cv_rmse,
        f.times,
    )  # fmt: skip


class BoardMaps:
    """A MapProvider over the live map's board (``board.latest()``: target -> MapGrid)."""

    def __init__(self, board, lat0: float, lon0: float) -> None:  # type: ignore[no-untyped-def]
        self.board, self.lat0, self.lon0 = board, lat0, lon0

    def __call__(self) -> MapSnapshot | None:
        grids = self.board.latest()
        cur = grids.get("current")
        if cur is None:
            return None
        fields = {}
        for name in ("current", "wind"):
            g = grids.get(name)
            if g is None:
                fields[name] = Field.still()
                continue
            dx, dy = LocalFrame(self.lat0, self.lon0).to_local(np.array(g.lat0), np.array(g.lon0))
            fields[name] = moved(g.to_field(), float(dx), float(dy))
        maps = Maps(fields["current"], fields["wind"], self.lat0, self.lon0)
        return MapSnapshot(maps, float(cur.t_fit), int(cur.n_samples))
