"""The live maps of current, wind and depth: samples in, `MapGrid`s out, every N seconds and at each line's end.

Time is the samples' own (their ``t``), so a replay at any speed and a test give the same maps. The
policy: an update (rank-one statistics, new posterior, new grid) every ``every_s`` and at the end of a
line; a hyperparameter refit (`forcemap fit`'s path) at the first update with enough samples, then
every ``refit_every_s`` or when the samples have doubled since the last one. Between refits, an
update adds the new samples as rank-one updates while a fresh fit on all samples would build the
same basis (`Component.same_basis`: the box's centre, axes and half-widths within 0.3 %); otherwise
(a sample past the box, or the samples' principal axes turned) it rebuilds the basis over all
samples with the kept hyperparameters ("basis rebuilt"). So a published map's basis covers every
sample in it (`MapGrid.basis_covers`), the map is the fresh fit's with these hyperparameters, and
what differs from a fresh `forcemap fit` is the hyperparameters' age (`MapGrid.hyper_age_s`,
`n_hyper`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from forcemap.host.live.growing import Component, MapGrid, grid_over, live_survey
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import MIN_ROWS
from forcemap.host.workbench.survey.target_rows import target_rows
from forcemap.host.workbench.terms.spec import BASELINE

TARGETS: dict[str, tuple[str, ...]] = {
    "current": ("current_east", "current_north"),
    "wind": ("wind_east", "wind_north"),
    "depth": ("depth",),
}
COLUMNS = ("t", "lat", "lon", "cog", "depth", "current_east", "current_north", "wind_east",
           "wind_north")  # fmt: skip
EVERY_S = 60.0
REFIT_EVERY_S = 300.0
TURN_DEG = 60.0  # a course this far off the line's for TURN_SAMPLES samples ends the line
TURN_SAMPLES = 3
MIN_LINE_S = 30.0


@dataclass
class LineWatcher:
    """Notices the end of a survey line: the course over ground leaves the line's course."""

    course: float | None = None
    started: float | None = None
    off: int = 0

    def see(self, t: float, cog: float | None) -> bool:
        if cog is None or not math.isfinite(cog):
            return False
        if self.course is None or self.started is None:
            self.course, self.started, self.off = cog, t, 0
            return False
        diff = abs((cog - self.course + 180.0) % 360.0 - 180.0)
        if diff <= TURN_DEG:
            self.off = 0
            a = math.radians(self.course) + 0.2 * math.radians(
                (cog - self.course + 180) % 360 - 180
            )
            self.course = math.degrees(a) % 360.0
            return False
        self.off += 1
        if self.off < TURN_SAMPLES:
            return False
        ended = t - self.started >= MIN_LINE_S
        self.course, self.started, self.off = cog, t, 0
        return ended


@dataclass
class TargetState:
    comps: list[Component]
    lat0: float
    lon0: float
    t_hyper: float
    n_refit: int  # rows of the columns at the last hyperparameter refit
    n_hyper: int  # samples of this target the hyperparameters were fitted on
    t_applied: float  # the newest sample's time in the statistics
    rebases: int = 0


@dataclass
class LiveMaps:
    """The in-process live maps; `mapproc.MapProcess` runs one in its own process."""

    every_s: float = EVERY_S
    refit_every_s: float = REFIT_EVERY_S
    terms: list[str] = field(default_factory=lambda: list(BASELINE))
    rows: dict[str, list[float]] = field(default_factory=lambda: {c: [] for c in COLUMNS})
    state: dict[str, TargetState] = field(default_factory=dict)
    latest: dict[str, MapGrid] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)
    lines: LineWatcher = field(default_factory=LineWatcher)
    last_update: float | None = None
    line_end: bool = False
    refits: int = 0
    rebases: int = 0
    updates: int = 0

    @property
    def n(self) -> int:
        return len(self.rows["t"])

    def add(self, sample: dict[str, Any]) -> None:
        """One `/samples` row (its JSON); rows without a time or position are skipped."""
        vals = {c: sample.get(c) for c in COLUMNS}
        if any(not isinstance(vals[c], int | float) for c in ("t", "lat", "lon")):
            return
        for c in COLUMNS:
            v = vals[c]
            self.rows[c].append(float(v) if isinstance(v, int | float) else math.nan)
        if self.lines.see(float(vals["t"]), vals["cog"]):
            self.line_end = True

    def due(self) -> str:
        """Why an update is due now ("" if none)."""
        if not self.n:
            return ""
        t = self.rows["t"][-1]
        if self.line_end:
            return "line end"
        if self.last_update is None or t - self.last_update >= self.every_s:
            return f"every {self.every_s:g}s"
        return ""

    def step(self, force: str = "", refit: bool = False) -> list[MapGrid]:
        """Update the maps if due (or ``force``: the reason; ``refit``: hyperparameters too); the maps
        updated."""
        reason = force or self.due()
        if not reason:
            return []
        self.line_end = False
        self.last_update = self.rows["t"][-1]
        cols = {c: np.asarray(v, float) for c, v in self.rows.items()}
        out = []
        for target, columns in TARGETS.items():
            try:
                grid = self._update(target, columns, cols, reason, refit)
            except WorkbenchError as exc:
                self.notes[target] = str(exc)
                continue
            if grid is not None:
                self.notes.pop(target, None)
                self.latest[target] = grid
                out.append(grid)
        self.updates += 1
        return out

    def _needs_refit(self, st: TargetState | None, cols: dict[str, np.ndarray]) -> bool:
        if st is None:
            return True
        return cols["t"][-1] - st.t_hyper >= self.refit_every_s or self.n >= 2 * st.n_refit

    def _update(self, target, columns, cols, reason, refit=False) -> MapGrid | None:
        known = np.ones(self.n, bool)
        for c in columns:
            known &= np.isfinite(cols[c])
        if known.sum() < MIN_ROWS:
            self.notes[target] = f"{int(known.sum())} samples with {target} so far"
            return None
        st = self.state.get(target)
        # the rows `forcemap fit` keeps: those with the target, less a position jump and its spikes
        survey = target_rows(live_survey(cols, []), columns[0]).survey
        if refit or self._needs_refit(st, cols):
            comps = [Component.refit(survey, c, self.terms) for c in columns]
            st = TargetState(comps, survey.lat0, survey.lon0, float(cols["t"][-1]), self.n,
                             survey.n, 0.0)  # fmt: skip
            self.state[target] = st
            self.refits += 1
            reason = f"{reason}; hyperparameters refitted"
        else:
            xy = np.column_stack(LocalFrame(st.lat0, st.lon0).to_local(survey.columns["lat"], survey.columns["lon"]))  # fmt: skip
            new = survey.columns["t"] > st.t_applied
            if all(comp.same_basis(xy) for comp in st.comps):
                for comp in st.comps:
                    comp.add(xy[new], survey.columns[comp.column][new])
            else:  # a fresh fit's basis, over all samples, with the same hyperparameters
                st.comps = [Component.refit(survey, c.column, self.terms, like=c) for c in st.comps]
                st.lat0, st.lon0 = survey.lat0, survey.lon0
                st.rebases += 1
                self.rebases += 1
                reason = f"{reason}; basis rebuilt"
        st.t_applied = float(survey.columns["t"].max())
        xy = np.column_stack(LocalFrame(st.lat0, st.lon0).to_local(survey.columns["lat"], survey.columns["lon"]))  # fmt: skip
        return self._grid(target, st, cols, xy, reason)

    def _grid(self, target: str, st: TargetState, cols, xy_all, reason: str) -> MapGrid:
        x0, y0, step, nx, ny = grid_over(xy_all)  # the grid follows the samples
        gx, gy = np.meshgrid(x0 + step * np.arange(nx), y0 + step * np.arange(ny))
        xy = np.column_stack([gx.ravel(), gy.ravel()])
        fields: dict[str, np.ndarray] = {}
        for comp in st.comps:
            mu, sd = comp.predict(xy)
            name = comp.column.split("_")[-1] if target != "depth" else "depth"
            fields[name], fields[f"{name}_sd"] = mu.reshape(gx.shape), sd.reshape(gx.shape)
        if "east" in fields:
            fields["speed"] = np.hypot(fields["east"], fields["north"])
            fields["speed_sd"] = np.hypot(fields["east_sd"], fields["north_sd"]) / math.sqrt(2.0)
        n = int(min(c.n for c in st.comps))
        covers = all(comp.covers(xy_all) for comp in st.comps)
        return MapGrid(target, st.lat0, st.lon0, x0, y0, step, fields, n, float(cols["t"][-1]),
                       float(st.t_hyper), reason, n_hyper=st.n_hyper, basis_covers=covers,
                       terms=list(self.terms))  # fmt: skip
