"""What every model of one survey shares: the rows that set the hyperparameters, the flow frame of a vector,
the depth map, derived covariates, and the inputs of models and maps (`SurveyFits`, one per survey)."""

from __future__ import annotations

import functools

import numpy as np
from forcemap.host.vessel.geodesy import wrap_from_minus180
from forcemap.host.workbench.engine.model import (
    HYPER_SPACING_S,
    MIN_HYPER_ROWS,
    DesignCache,
    Model,
    spaced_rows,
)
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey import reference
from forcemap.host.workbench.survey.gaps import DERIVED_INPUTS, bridged, prepare_column, too_few
from forcemap.host.workbench.survey.table import (
    MIN_ROWS,
    Survey,
    VectorTarget,
    is_circular,
    unit_of,
)
from forcemap.host.workbench.survey.target_rows import target_rows
from forcemap.host.workbench.targets.axis_choice import AxisChoice, ReferenceAxis, choose_axis
from forcemap.host.workbench.targets.flow_axis import along_reference, axis_frame, time_part
from forcemap.host.workbench.terms.registry import build_term
from forcemap.host.workbench.terms.spec import BASELINE, parse_terms

# the names callers have always found here (hyperparameters come from samples HYPER_SPACING_S apart)
__all__ = ["HYPER_SPACING_S", "MIN_HYPER_ROWS", "SurveyFits", "hyper_rows", "survey_fits"]


def circular_median(deg: np.ndarray) -> float:
    r = np.radians(deg)
    return float(np.degrees(np.arctan2(np.sin(r).mean(), np.cos(r).mean())) % 360.0)


# a speed target's frame follows the flow in time too (a veering wind still has a meaningful local
# direction, and the along-flow component stays close to the speed); a direction target's must not
FRAME_TERMS = {"speed": [*BASELINE, "gp(t, matern32)"], "dir": list(BASELINE)}
FRAME_MAX_BASIS = 800  # the frame is a smooth direction field; it needs no fine spatial detail
DERIVED = tuple(DERIVED_INPUTS)


def terms_with_basis(terms, n_basis=None) -> list:
    """Built terms (from specs or strings), the GP terms with the basis sizes `n_basis` gives by term name
    (`Model.n_basis_` of an earlier fit)."""
    specs = parse_terms(terms, is_circular) if all(isinstance(t, str) for t in terms) else terms
    built = [build_term(t, is_circular) for t in specs]
    for t in built:
        if t.grows_basis and n_basis and t.describe() in n_basis:
            t.n_basis = int(n_basis[t.describe()])
            t.max_basis = max(t.max_basis, t.n_basis)
    return built


class SurveyFits:
    """What every model of one survey shares, each computed once on first use: the rows that set the
    hyperparameters, the depth map, the flow frames and the secondary (across/along) components of
    vectors, the frames refitted per CV split, and derived covariates. Get it with `survey_fits(survey)`."""

    def __init__(self, survey: Survey) -> None:
        self.survey = survey
        self._frame_cv: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self._axes: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}
        self._axis: dict[tuple, AxisChoice] = {}
        self._derived: dict[str, np.ndarray] = {}
        # hyperparameters of the shared models from an earlier fit on this survey (`shared_hypers`), by key:
        # the models are then rebuilt without the optimiser, the same maps
        self.saved: dict[str, dict] = {}
        # the flow frames and secondary components fitted so far, by the same keys
        self._shared: dict[str, Model] = {}
        # Gram matrices shared by models of the same features (a vector's components); `plan` is the
        # cross-validation folds to accumulate with them
        self.grams = DesignCache()

    @functools.cached_property
    def hyper_rows(self) -> np.ndarray | None:
        """Rows for the hyperparameters: the first sample of every HYPER_SPACING_S (None: all rows), what
        `Model(hyper_spacing_s=HYPER_SPACING_S)` picks on the survey's times (see `model.spaced_rows`)."""
        return spaced_rows(self.survey.trel, HYPER_SPACING_S)

    def model(self, terms, **kw) -> Model:
        """An unfitted model with the survey's hyperparameter spacing, sharing its Gram matrices."""
        return Model(terms, hyper_spacing_s=HYPER_SPACING_S, memory=self.grams, **kw)

    @functools.cached_property
    def depth_map(self) -> Model:
        """The baseline model of depth over position, fitted on the rows a depth map is fitted on (its
        spikes and the soundings the depth surface rejects left out: `target_rows`): maps evaluate depth
        terms on it."""
        s = self.survey
        s.column("depth")  # a clear error where the table has none
        s = target_rows(s, "depth").survey
        prepare_column(s, "depth", "covariate")  # not constant
        return self.model(BASELINE).fit({"position": s.xy, "t": s.trel}, s.columns["depth"])

    def frame(self, vt: VectorTarget, time_terms: tuple[str, ...] = ()) -> tuple[Model, Model]:
        """Smooth models of a vector's east and north components (see `flow_frame`); with `time_terms`
        (a tide, a seiche) over position and those terms, for the oscillating flow's axis (`flow_axis`)."""
        kind = "dir" if vt.aspect == "dir" else "speed"
        terms = FRAME_TERMS[kind] if not time_terms else [*BASELINE, *time_terms]
        key = f"frame/{vt.prefix}/{kind}" + "".join(f"/{t}" for t in time_terms)
        if key + "/east" not in self._shared:
            survey = self.survey
            e, n = survey.components(vt)
            if e is None:
                raise WorkbenchError(f"the table has no {vt.prefix} components, speed or direction")
            # fitted on the rows that have the vector; it predicts the direction on every row
            ok = np.isfinite(e) & np.isfinite(n)
            if ok.sum() < MIN_ROWS:
                raise too_few(int(ok.sum()), vt.prefix)
            X = {k: v[ok] for k, v in survey_inputs(survey, set()).items()}
            for c, y in (("east", e[ok]), ("north", n[ok])):
                self._fit(f"{key}/{c}", terms, X, y, max_basis=FRAME_MAX_BASIS)
        return self._shared[key + "/east"], self._shared[key + "/north"]

    def secondary(
        self,
        vt: VectorTarget,
        primary_is_along: bool,
        y: np.ndarray,
        time_terms: tuple = (),
        max_basis: int | None = None,
        one_axis: bool = False,
    ) -> Model:
        """The baseline model (with the target's time terms: a tide moves both components) of the
        flow-frame component a target's other terms do not act on (`y`, in the frame `one_axis` names), at
        the primary's basis cap `max_basis`: a speed is judged with both components at one spatial
        resolution."""
        key = f"secondary/{vt.prefix}/{'across' if primary_is_along else 'along'}"
        key += "".join(f"/{t}" for t in time_terms) + ("/one-axis" if one_axis else "")
        key += "" if max_basis is None else f"/basis<={max_basis}"
        if key not in self._shared:
            X = survey_inputs(self.survey, set())
            self._fit(key, [*BASELINE, *time_terms], X, y, max_basis=max_basis)
        return self._shared[key]

    def _fit(self, key: str, terms, X: dict, y: np.ndarray, **kw) -> Model:
        """A shared model, fitted anew or rebuilt from its saved hyperparameters; kept for `shared_hypers`."""
        saved = self.saved.get(key)
        if saved is None:
            model = self.model(terms, **kw).fit(X, y)
        else:
            built = terms_with_basis(terms, saved["n_basis"])
            init = np.asarray(saved["theta"], float)
            model = self.model(built, init=init, optimize=False, **kw).fit(X, y)
        self._shared[key] = model
        return model

    def shared_hypers(self) -> dict[str, dict]:
        """The hyperparameters and basis sizes of every shared model fitted so far (for `saved`)."""
        return {
            k: {"theta": [float(v) for v in m.theta_], "n_basis": dict(m.n_basis_)}
            for k, m in self._shared.items()
        }

    def axis(self, vt: VectorTarget, time_terms: tuple) -> AxisChoice:
        """Whether a vector with time terms is modelled along one axis for the survey or the axis at each
        place (host/workbench/targets/axis_choice.py), chosen once."""
        key = (vt.prefix, vt.aspect, time_terms)
        if key not in self._axis and along_reference(time_terms):
            used = reference.stations_used(self.survey)
            self._axis[key] = ReferenceAxis(tuple(s.id for s in used))  # type: ignore[assignment]
        if key not in self._axis:
            self._axis[key] = choose_axis(self, vt, time_terms)
        return self._axis[key]

    def frame_axes(
        self, vt: VectorTarget, time_terms: tuple, one_axis: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """The oscillating flow's axis at each sample, from the frame models fitted on every row."""
        key = (vt.prefix, vt.aspect, time_terms, one_axis)
        if key not in self._axes and along_reference(time_terms):
            self._axes[key] = reference.flood_axes(self.survey, self.survey.xy)
        if key not in self._axes:
            me, mn = self.frame(vt, time_terms)
            X = survey_inputs(self.survey, set())
            self._axes[key] = axis_frame(me, mn, self.survey, X, one_axis=one_axis)
        return self._axes[key]

    def frame_cv(
        self,
        vt: VectorTarget,
        folds: np.ndarray,
        time_terms: tuple = (),
        one_axis: bool | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The flow frame's unit vector at each sample from the frame models refitted without its fold
        (with time terms: in the frame `one_axis` names, by default the one `axis` chose)."""
        if along_reference(time_terms):  # the reference's axes: nothing learned from the fold
            return reference.flood_axes(self.survey, self.survey.xy)
        if time_terms and one_axis is None:
            one_axis = self.axis(vt, time_terms).one_axis
        key = (vt.prefix, vt.aspect, np.ascontiguousarray(folds).tobytes(), time_terms, one_axis)
        if key not in self._frame_cv:
            me, mn = self.frame(vt, time_terms)
            e = me.cv_predict(folds, return_std=False)[0]
            n = mn.cv_predict(folds, return_std=False)[0]
            if time_terms:
                X = survey_inputs(self.survey, set())
                mean = (e - time_part(me, X), n - time_part(mn, X))
                self._frame_cv[key] = axis_frame(me, mn, self.survey, X, mean, bool(one_axis))
                return self._frame_cv[key]
            sp = np.hypot(e, n)
            sp = np.where(sp > 1e-9, sp, 1.0)
            self._frame_cv[key] = (e / sp, n / sp)
        return self._frame_cv[key]

    def derived(self, name: str) -> np.ndarray:
        """A derived covariate (see `derived_column`)."""
        if name not in self._derived:
            self._derived[name] = _derive(self.survey, name)
        return self._derived[name]


def survey_fits(survey: Survey) -> SurveyFits:
    """The survey's shared fits, kept with it under one key."""
    fits = survey.cache.get(SurveyFits)
    if fits is None:
        fits = survey.cache[SurveyFits] = SurveyFits(survey)
    return fits


def flow_frame(survey: Survey, vt: VectorTarget) -> tuple[Model, Model]:
    """Smooth models of a vector's east and north components (fitted once per survey).

    For a speed target they are over position and time, so the frame follows a wind that veers and the
    along-flow component stays close to the speed. For a direction target they are over position only:
    the frame is then a reference direction that must not follow anything the diagnosis should find (with
    time in it, it followed every leg-by-leg change, a compass deviation or a veer, and the direction's
    residual had nothing left to explain). Their hyperparameters come from `hyper_rows`."""
    return survey_fits(survey).frame(vt)


def frame_direction(
    survey: Survey,
    vt: VectorTarget,
    xy: np.ndarray,
    t: np.ndarray | None = None,
    time_terms: tuple[str, ...] = (),
) -> tuple[np.ndarray, np.ndarray]:
    """Unit vector of the smooth flow at positions `xy` and survey times `t` (default: mid-survey); with
    `time_terms` (a tide, a seiche), the oscillating flow's axis there, which does not change in time (at
    each place or one for the survey, as `SurveyFits.axis` chose)."""
    if along_reference(time_terms):
        return reference.flood_axes(survey, xy)
    fits = survey_fits(survey)
    me, mn = fits.frame(vt, time_terms)
    if t is None:
        t = np.full(len(xy), float(np.median(survey.trel)))
    X = {"position": xy, "t": t, "utc": survey.t0 + t, "lat": np.full(len(xy), survey.lat0)}
    if time_terms:
        return axis_frame(me, mn, survey, X, one_axis=fits.axis(vt, time_terms).one_axis)
    e, n = me.predict(X), mn.predict(X)
    s = np.hypot(e, n)
    s = np.where(s > 1e-9, s, 1.0)
    return e / s, n / s


def derived_column(survey: Survey, name: str) -> np.ndarray:
    """A covariate by name: a table column, or a derived one (computed once per survey, never added to its
    columns): `heading_rel_current` / `heading_rel_wind`, the bow's angle to the baseline flow, and `stw`,
    the boat's speed through the water (ground velocity minus the measured current)."""
    if name in survey.columns or name not in DERIVED:
        return survey.column(name)
    return survey_fits(survey).derived(name)


def _derive(survey: Survey, name: str) -> np.ndarray:
    if name == "stw":
        need = ("sog", "cog", "current_east", "current_north")
        missing = [c for c in need if c not in survey.columns]
        if missing:
            raise WorkbenchError(f"'stw' needs the columns {', '.join(missing)} in the table")
        # each reading bridged within its own correlation time; NaN where one has a longer gap
        sog, cog, ce, cn = (bridged(survey, c) for c in need)
        cog = np.radians(cog)
        return np.hypot(sog * np.sin(cog) - ce, sog * np.cos(cog) - cn)
    if "heading" not in survey.columns:
        raise WorkbenchError(f"'{name}' needs the column heading in the table")
    vt = survey.vector_target("current_speed" if name.endswith("current") else "wind_speed")
    if vt is None:
        raise WorkbenchError(f"'{name}' needs {name.rsplit('_', 1)[1]} columns in the table")
    ue, un = frame_direction(survey, vt, survey.xy, survey.trel)
    flow = np.degrees(np.arctan2(ue, un))
    if vt.is_from:
        flow = flow + 180.0
    return wrap_from_minus180(bridged(survey, "heading") - flow)


def covariate(survey: Survey, name: str) -> np.ndarray:
    """A covariate ready for modelling: a prepared table column, or a derived one."""
    if name in survey.columns or name not in DERIVED:
        return prepare_column(survey, name, "covariate")
    values = derived_column(survey, name)
    if not np.isfinite(values).all():
        missing = int((~np.isfinite(values)).sum())
        raise WorkbenchError(
            f"covariate '{name}' has no value on {missing} of {len(values)} rows (one of "
            f"{', '.join(DERIVED_INPUTS[name])} is missing there for longer than its correlation time)"
        )
    if np.ptp(values) <= 1e-12 * max(1.0, float(np.abs(values).max())):
        raise WorkbenchError(f"covariate '{name}' is constant; there is nothing to model")
    return values


# inputs every model can have without a column of their own: where and when (`utc`: UNIX seconds, the
# tide's clock; `t`: seconds since the survey's first sample; `lat`: degrees, the tide's latitude factors;
# `reference`: a reference current's prediction and rate there, survey/reference.py)
PLACE_AND_TIME = ("position", "t", "utc", "lat", "reference")


def survey_inputs(survey: Survey, names: set[str]) -> dict[str, np.ndarray]:
    X: dict[str, np.ndarray] = {
        "position": survey.xy,
        "t": survey.trel,
        "utc": survey.columns["t"],
        "lat": survey.columns["lat"],
    }
    if survey.reference is not None or reference.INPUT in names:
        X[reference.INPUT] = reference.survey_rows(survey)
    for name in names - set(PLACE_AND_TIME):
        X[name] = covariate(survey, name)
    return X


def mid_time(survey: Survey) -> float:
    """UNIX time of the survey's median sample: when a map without a time is evaluated."""
    return survey.t0 + float(np.median(survey.trel))


def grid_inputs(
    survey: Survey, names: set[str], xy: np.ndarray, at: float | np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """Inputs for maps: depth from a depth map, time `at` (UNIX s, one or per point; default mid-survey),
    every other covariate at its typical value."""
    utc = np.broadcast_to(np.asarray(mid_time(survey) if at is None else at, float), (len(xy),))
    X: dict[str, np.ndarray] = {
        "position": xy,
        "t": utc - survey.t0,
        "utc": utc,
        "lat": np.full(len(xy), survey.lat0),
    }
    if survey.reference is not None or reference.INPUT in names:
        X[reference.INPUT] = reference.inputs_at(survey, xy, utc)
    for name in names - set(PLACE_AND_TIME):
        if name == "depth":
            X[name] = survey_fits(survey).depth_map.predict({"position": xy})
        else:
            X[name] = np.full(len(xy), typical_value(survey, name))
    return X


def typical_value(survey: Survey, name: str) -> float:
    """The value a map holds a covariate at (`grid_inputs`): its median over the survey (an angle's
    circular median)."""
    values = survey_inputs(survey, {name})[name]
    return circular_median(values) if is_circular(name) else float(np.median(values))


def held_notes(survey: Survey, specs) -> list[str]:
    """One line per term a map draws with a covariate held at its typical value (`grid_inputs`: not
    place, time or depth, which the map has at every cell): the term, the covariate and its value."""
    out = []
    for spec in specs:
        held = [n for n in spec.inputs if n not in PLACE_AND_TIME and n != "depth"]
        if not held:
            continue
        values = ", ".join(
            f"{n} = {typical_value(survey, n):.3g}{' ' + u if (u := unit_of(n)) else ''}"
            for n in held
        )
        out.append(
            f"{spec} drawn at {values} everywhere (the survey's median; `plan` leaves the term out)"
        )
    return out


def hyper_rows(survey: Survey) -> np.ndarray | None:
    """Rows whose marginal likelihood sets the hyperparameters (see `SurveyFits.hyper_rows`)."""
    return survey_fits(survey).hyper_rows
