"""Current and wind maps for planning: the survey's latest fits, as vector fields on a grid with their uncertainty.

A vector is mapped through its east and north components, each with the terms of the workspace's latest
fit of its speed (`forcemap fit` is run first if there is none). Every term the planner can evaluate
along a future track is kept: position, time (held at mid-survey: the map is the survey's average
state) and depth (from the survey's depth map at each grid point, as the workbench's own maps do).
Terms in what a future track does not know (heading, speed, a clock offset) are left out, with a note.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from forcemap.host.progress import note
from forcemap.host.workbench.engine.model import HYPER_SPACING_S, DesignCache, Model, small_blas
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.fits.workspace import current_terms, workspace_dir
from forcemap.host.workbench.survey import reference
from forcemap.host.workbench.survey.table import Survey, is_circular
from forcemap.host.workbench.survey.target_rows import target_rows
from forcemap.host.workbench.targets.flow_axis import along_reference
from forcemap.host.workbench.targets.survey_fits import (
    grid_inputs,
    mid_time,
    survey_fits,
    survey_inputs,
)
from forcemap.host.workbench.terms import registry
from forcemap.host.workbench.terms.registry import parse_term
from forcemap.host.workbench.terms.spec import BASELINE
from forcemap.host.workbench.validation.cv import blocked_folds

GRID_STEP_M = 4.0
MAX_BASIS = 800  # a current or wind field steering a boat needs no detail finer than ~30 m
# what a future track is known by: where it is (and so the depth there, from the depth map), and when
PLANNABLE_INPUTS = {"position", "t", "depth", "utc", "lat", "reference"}
# a field that changes in time is gridded at times this fraction of its shortest period apart (linear
# interpolation between them is then within 1 % of the amplitude), at least MIN_STEP_S apart ...
SLICES_PER_PERIOD = 24
MIN_STEP_S, GP_STEP_S = (
    60.0,
    600.0,
)  # ... and every GP_STEP_S for a GP in time (it reverts to its mean)
MAX_SLICES = 97


@dataclass
class Field:
    """A gridded vector field (m/s, the velocity of the medium) with the predictive standard deviation of each
    component (what a new measurement would differ by: the mean's and the noise's), and the components'
    blocked-CV RMSE (`cv_rmse`, m/s: how far the map was from held-out measurements).

    With `times` (UNIX s, evenly spaced) the arrays are (nt, ny, nx): the field at each of those times, and
    between them linear in time (a tide's or a seiche's current, predicted along the mission); a time
    before the first or after the last is held at that slice."""

    x0: float
    y0: float
    step: float
    east: np.ndarray  # (ny, nx), or (nt, ny, nx) with `times`
    north: np.ndarray
    east_sd: np.ndarray
    north_sd: np.ndarray
    terms: list[str] = field(default_factory=list)
    cv_rmse: float = 0.0
    times: np.ndarray | None = None
    _lists: tuple = field(default=(), repr=False)

    def _slices(self) -> tuple:
        if not self._lists:
            ny, nx = self.east.shape[-2:]
            e = self.east if self.times is not None else self.east[None]
            n = self.north if self.times is not None else self.north[None]
            self._lists = (
                [a.tolist() for a in e],
                [a.tolist() for a in n],
                nx - 1.000001,
                ny - 1.000001,
            )
        return self._lists

    def _bilinear(self, k: int, x: float, y: float) -> tuple[float, float]:
        es, ns, fx_max, fy_max = self._slices()
        fx = (x - self.x0) / self.step
        fy = (y - self.y0) / self.step
        fx = 0.0 if fx < 0.0 else (fx_max if fx > fx_max else fx)
        fy = 0.0 if fy < 0.0 else (fy_max if fy > fy_max else fy)
        i, j = int(fx), int(fy)
        a, b = fx - i, fy - j
        e, n = es[k], ns[k]
        e0, e1, n0, n1 = e[j], e[j + 1], n[j], n[j + 1]
        ve = (1 - b) * ((1 - a) * e0[i] + a * e0[i + 1]) + b * ((1 - a) * e1[i] + a * e1[i + 1])
        vn = (1 - b) * ((1 - a) * n0[i] + a * n0[i + 1]) + b * ((1 - a) * n1[i] + a * n1[i + 1])
        return ve, vn

    def slice_at(self, t: float | None) -> tuple[int, float]:
        """The slice before UNIX time `t` and the weight of the one after (0: none)."""
        if self.times is None or t is None or len(self.times) < 2:
            return 0, 0.0
        f = (t - self.times[0]) / (self.times[1] - self.times[0])
        last = len(self.times) - 1
        if f <= 0.0:
            return 0, 0.0
        if f >= last:
            return last, 0.0
        k = int(f)
        return k, f - k

    def at(
        self, x: float, y: float, scale: float = 1.0, t: float | None = None
    ) -> tuple[float, float]:
        """Bilinear (east, north) at one point (the edge value outside the grid), linear in time between
        slices at UNIX time `t`; ``scale`` x the field."""
        k, w = self.slice_at(t)
        ve, vn = self._bilinear(k, x, y)
        if w > 0.0:
            ve1, vn1 = self._bilinear(k + 1, x, y)
            ve, vn = ve + w * (ve1 - ve), vn + w * (vn1 - vn)
        return scale * ve, scale * vn

    def sample(
        self, xy: np.ndarray, t: float | np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(east, north, speed standard deviation) at many points (nearest grid node; the nearest slice to
        UNIX time `t`, one or per point; without `t` the mean over the slices, with their spread in it)."""
        ny, nx = self.east.shape[-2:]
        i = np.clip(np.rint((xy[:, 0] - self.x0) / self.step).astype(int), 0, nx - 1)
        j = np.clip(np.rint((xy[:, 1] - self.y0) / self.step).astype(int), 0, ny - 1)
        if self.times is None:
            sd = np.hypot(self.east_sd[j, i], self.north_sd[j, i]) / math.sqrt(2.0)
            return self.east[j, i], self.north[j, i], sd
        if t is None:
            e, n = self.east[:, j, i], self.north[:, j, i]
            sd = np.hypot(self.east_sd[:, j, i], self.north_sd[:, j, i]).mean(axis=0) / math.sqrt(
                2.0
            )
            return e.mean(axis=0), n.mean(axis=0), np.hypot(sd, np.hypot(e.std(0), n.std(0)))
        dt = self.times[1] - self.times[0] if len(self.times) > 1 else 1.0
        k = np.clip(np.rint((np.asarray(t, float) - self.times[0]) / dt), 0, len(self.times) - 1)
        k = np.broadcast_to(k.astype(int), i.shape)
        sd = np.hypot(self.east_sd[k, j, i], self.north_sd[k, j, i]) / math.sqrt(2.0)
        return self.east[k, j, i], self.north[k, j, i], sd

    @classmethod
    def still(cls) -> Field:
        z = np.zeros((2, 2))
        return cls(0.0, 0.0, 1e6, z, z, z, z, ["none"])


@dataclass
class Maps:
    """What the planner knows of the water and the air, in the survey's local frame."""

    current: Field
    wind: Field
    lat0: float
    lon0: float
    notes: list[str] = field(default_factory=list)
    start: float | None = None  # UNIX s when the mission starts: a field in time is read from there


def _inputs(term: str) -> set[str] | None:
    try:
        return set(parse_term(term, is_circular).inputs)
    except Exception:  # a clock offset or anything else that is not a map term
        return None


def plannable_terms(terms: list[str]) -> tuple[list[str], list[str]]:
    """(terms evaluable along a future track, terms left out)."""
    keep, drop = [], []
    for t in terms:
        inputs = _inputs(t)
        (keep if inputs is not None and inputs <= PLANNABLE_INPUTS else drop).append(t)
    return (keep or list(BASELINE)), drop


def _term_inputs(terms: list[str]) -> set[str]:
    return set().union(*(_inputs(t) or set() for t in terms))


def with_depth_known(survey: Survey, terms: list[str]) -> tuple[list[str], list[str]]:
    """``terms``, less the depth terms when the survey cannot give a depth map (no usable depth)."""
    if "depth" not in _term_inputs(terms):
        return terms, []
    try:
        survey_fits(survey).depth_map  # noqa: B018 - fitted on the rows that have depth, or refused
    except WorkbenchError as exc:
        keep = [t for t in terms if "depth" not in (_inputs(t) or set())]
        return (keep or list(BASELINE)), [f"depth terms left out: no depth map ({exc})"]
    return terms, []


def latest_terms(table: Path, survey: Survey, target: str, progress: bool) -> list[str]:
    """Terms of the workspace's latest fit of ``target``; fit the baseline and record it if there is none."""
    ws = workspace_dir(table)
    terms = current_terms(ws, target)
    if terms is None:
        from forcemap.host.workbench.fits.fit import fit_target, record

        note(f"no fit of {target} in {ws}: fitting the baseline first", progress)
        record(table, fit_target(survey, target, list(BASELINE), progress=progress))
        terms = current_terms(ws, target) or list(BASELINE)
    return terms


def _grid(bounds: tuple[float, float, float, float], step: float) -> tuple[np.ndarray, np.ndarray]:
    x0, x1, y0, y1 = bounds
    gx = np.arange(x0, x1 + step, step)
    gy = np.arange(y0, y1 + step, step)
    return gx, gy


def fit_field(
    survey: Survey,
    prefix: str,
    terms: list[str],
    bounds: tuple[float, float, float, float],
    step: float = GRID_STEP_M,
    cv: bool = True,
    times: np.ndarray | None = None,
) -> Field:
    """Fit the east and north components of ``prefix`` and predict them, with their predictive std, on a
    grid over ``bounds``, on the rows that have the vector (its spikes left out unless the survey keeps
    outliers; `target_rows`); with ``cv``, also their blocked-CV RMSE (an in-flight refit skips it: it
    must be quick, and its sd is what it has). With ``times`` (UNIX s) the grid is predicted at each of
    them (a field in time); else at mid-survey."""
    names = _term_inputs(terms) | {"position", "t"}
    survey = target_rows(survey, f"{prefix}_speed", names).survey
    vt = survey.vector_target(f"{prefix}_speed")
    e, n = survey.components(vt)  # type: ignore[arg-type]
    X = survey_inputs(survey, names)
    gx, gy = _grid(bounds, step)
    GX, GY = np.meshgrid(gx, gy)
    xy = np.column_stack([GX.ravel(), GY.ravel()])
    # the grid's inputs: time at mid-survey (or each of `times`), depth from the survey's depth map
    grids = [grid_inputs(survey, names, xy, at) for at in ([None] if times is None else times)]
    out, sq = [], []
    grams = DesignCache()  # the east and north components share their features
    folds = blocked_folds(X["position"])[0]
    # a current on a reference: each component as its departure from the stations' prediction
    station = departures(survey, terms, xy, times)
    with small_blas():
        for k, comp in enumerate((e, n)):
            m = Model(terms, max_basis=MAX_BASIS, hyper_spacing_s=HYPER_SPACING_S, memory=grams)
            m.fit(X, comp - station[0][k])
            pred = [m.predict(G, return_std=True, include_noise=True) for G in grids]
            pred = [(p[0] + s[k], p[1]) for p, s in zip(pred, station[1], strict=True)]
            shape = GX.shape if times is None else (len(grids), *GX.shape)
            out += [
                np.reshape([p[0] for p in pred], shape),
                np.reshape([p[1] for p in pred], shape),
            ]
            if cv:
                held = m.cv_predict(folds, return_std=False)[0] + station[0][k]
                sq.append(float(np.mean((comp - held) ** 2)))
    rmse = math.sqrt(sum(sq) / len(sq)) if sq else 0.0  # per component, as the sds are
    times = None if times is None else np.asarray(times, float)
    return Field(
        float(gx[0]), float(gy[0]), step, out[0], out[2], out[1], out[3], list(terms), rmse, times
    )


def departures(survey: Survey, terms: list[str], xy: np.ndarray, times) -> tuple:
    """The stations' (east, north) prediction at the survey's rows and at the grid `xy` at each time
    (`times`, or mid-survey) where the terms relate the current to a reference (zeros otherwise), as
    targets/reference_part.py does for the workbench's vector targets."""
    slices = [None] if times is None else list(times)
    if survey.reference is None or not along_reference(tuple(terms)):
        return (0.0, 0.0), [(0.0, 0.0)] * len(slices)
    rows = reference.station_vector(survey, survey.xy, survey.columns["t"])
    grid = [reference.station_vector(survey, xy, mid_time(survey) if at is None else at)
            for at in slices]  # fmt: skip
    return rows, grid


def field_times(terms: list[str], start: float, span_s: float) -> np.ndarray | None:
    """When a field of `terms` is gridded along a mission from UNIX time `start` over `span_s`: None if
    nothing in it changes in time; else evenly, SLICES_PER_PERIOD to the shortest tide or seiche period
    (every GP_STEP_S for a GP in time alone), at most MAX_SLICES."""
    specs = [parse_term(t, is_circular) for t in terms if _inputs(t) is not None]
    if not any(registry.in_time(s) for s in specs):
        return None
    periods = [p for s in specs for p in registry.periods_s(s)]
    step = max(MIN_STEP_S, min(periods) / SLICES_PER_PERIOD) if periods else GP_STEP_S
    step = max(step, span_s / (MAX_SLICES - 1))
    return start + np.arange(0.0, span_s + step, step)


def survey_maps(
    table: Path,
    survey: Survey,
    bounds: tuple[float, float, float, float],
    progress: bool = True,
    start: float | None = None,
    span_s: float = 4 * 3600.0,
) -> Maps:
    """Current (and wind, when the table has it) over ``bounds`` (survey frame, m) from the latest fits.
    With a mission ``start`` (UNIX s), a field whose terms change in time (a tide, a seiche, a GP in
    time) is gridded at times over ``span_s`` from it: the current when the boat will be there."""
    notes: list[str] = []
    fields: dict[str, Field] = {}
    for prefix in ("current", "wind"):
        if survey.vector_target(f"{prefix}_speed") is None:
            notes.append(f"the table has no {prefix}: planning without it")
            fields[prefix] = Field.still()
            continue
        terms, dropped = plannable_terms(latest_terms(table, survey, f"{prefix}_speed", progress))
        if dropped:
            notes.append(
                f"{prefix}: left out {', '.join(dropped)} (not known along a future track)"
            )
        terms, no_depth = with_depth_known(survey, terms)
        notes += [f"{prefix}: {line}" for line in no_depth]
        if "depth" in _term_inputs(terms):
            notes.append(f"{prefix}: depth terms evaluated on the survey's depth map")
        rows = target_rows(survey, f"{prefix}_speed", _term_inputs(terms))
        notes += [f"{prefix}: {line}" for line in rows.lines()]
        notes += [f"{prefix}: {line}" for line in (rows.spikes.lines() if rows.spikes else [])]
        times = None if start is None else field_times(terms, start, span_s)
        when = "" if times is None else f" at {len(times)} times over the mission"
        note(
            f"mapping {prefix}: {' + '.join(terms)} on east and north components{when} ...",
            progress,
        )
        fields[prefix] = fit_field(survey, prefix, terms, bounds, times=times)
        if times is not None:
            notes += [f"{prefix}: {n}" for n in mission_time_notes(fields[prefix], survey, times)]
    return Maps(fields["current"], fields["wind"], survey.lat0, survey.lon0, notes, start)


def mission_time_notes(f: Field, survey: Survey, times: np.ndarray) -> list[str]:
    """What the field in time is: read at the times the boat will be there, and how far from the survey."""
    from forcemap.host.workbench.terms.time_terms import iso

    t1 = float(survey.columns["t"].max())
    lines = [
        f"{' + '.join(f.terms)} evaluated from {iso(times[0])} to {iso(times[-1])} every "
        f"{(times[1] - times[0]) / 60 if len(times) > 1 else 0:.0f} min: each leg is predicted in the "
        "current expected when the boat is on it"
    ]
    predicts = any(registry.caps(parse_term(t, is_circular)).predicts_in_time for t in f.terms)
    if times[0] > t1 and not predicts:
        lines.append(
            f"the mission starts {(times[0] - t1) / 3600:.1f} h after the survey: a GP in time has "
            "reverted to its mean there (a tide term predicts: fit --effects tide)"
        )
    return lines
