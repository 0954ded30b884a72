"""A model of one survey target: scalar columns directly, wind and current through their vector components.

Speed and direction targets are modelled in the local flow frame: the measured vector is split into its
component along and across a smooth baseline flow direction (a GP fit of the east and north components).
Effect terms act on the along-flow component for a speed target (an effect that changes speed scales the
flow) and on the across-flow component for a direction target (one that turns the flow deflects it).
Speed and direction, and their uncertainty, are derived from the two Gaussian components by sampling.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping

import numpy as np
from forcemap.host.workbench import clock_offset
from forcemap.host.workbench.cv import CVResult
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.model import Model
from forcemap.host.workbench.spec import BASELINE, build_term, parse_terms
from forcemap.host.workbench.table import (
    NOT_COVARIATES,
    Survey,
    VectorTarget,
    is_circular,
    prepare_column,
)
from forcemap.host.workbench.terms import HilbertGPTerm

N_DRAWS = 128
# hyperparameters come from samples this far apart in time (see hyper_rows), but never fewer than MIN_HYPER_ROWS
HYPER_SPACING_S = 5.0
MIN_HYPER_ROWS = 300


def wrap180(a: np.ndarray) -> np.ndarray:
    return (a + 180.0) % 360.0 - 180.0


def circular_median(deg: np.ndarray) -> float:
    r = np.radians(deg)
    return float(np.degrees(np.arctan2(np.sin(r).mean(), np.cos(r).mean())) % 360.0)


# a speed target's frame follows the flow in time too (a veering wind still has a meaningful local
# direction, and the along-flow component stays close to the speed); a direction target's must not
FRAME_TERMS = {"speed": [*BASELINE, "gp(t, matern32)"], "dir": list(BASELINE)}
FRAME_MAX_BASIS = 800  # the frame is a smooth direction field; it needs no fine spatial detail
DERIVED = ("stw", "heading_rel_current", "heading_rel_wind")


class SurveyFits:
    """What every model of one survey shares, each computed once on first use: the rows that set the
    hyperparameters, the depth map, the flow frames and the secondary (across/along) components of
    vectors, the frames refitted per CV split, and derived covariates. Get it with `survey_fits(survey)`."""

    def __init__(self, survey: Survey) -> None:
        self.survey = survey
        self._frames: dict[tuple[str, str], tuple[Model, Model]] = {}
        self._secondary: dict[tuple[str, bool], Model] = {}
        self._frame_cv: dict[tuple[str, str, bytes], tuple[np.ndarray, np.ndarray]] = {}
        self._derived: dict[str, np.ndarray] = {}

    @functools.cached_property
    def hyper_rows(self) -> np.ndarray | None:
        """Rows for the hyperparameters: the first sample of every HYPER_SPACING_S (None: all rows).

        Along a survey line the samples are a metre apart and their errors are correlated over seconds
        (paddle-wheel inertia, gusts, the sounder's 1 Hz updates, turns). Fed every sample, the marginal
        likelihood reads that as fine spatial structure: it puts the position lengthscale at the basis's
        limit, far below the line spacing, and the map then extrapolates wildly into any area it has not
        seen. Samples HYPER_SPACING_S apart are close to independent, so their marginal likelihood sets the
        hyperparameters; the posterior (the map) uses every sample."""
        survey = self.survey
        t = survey.trel
        _, rows = np.unique(np.floor((t - t.min()) / HYPER_SPACING_S), return_index=True)
        if len(rows) < MIN_HYPER_ROWS:
            rows = np.unique(
                np.linspace(0, survey.n - 1, min(MIN_HYPER_ROWS, survey.n)).astype(int)
            )
        return None if len(rows) >= survey.n else np.sort(rows)

    @functools.cached_property
    def depth_map(self) -> Model:
        """The baseline model of depth over position: maps evaluate depth terms on it."""
        depth = survey_inputs(self.survey, {"depth"})["depth"]
        model = Model(BASELINE, hyper_rows=self.hyper_rows)
        return model.fit({"position": self.survey.xy}, depth)

    def frame(self, vt: VectorTarget) -> tuple[Model, Model]:
        """Smooth models of a vector's east and north components (see `flow_frame`)."""
        kind = "dir" if vt.aspect == "dir" else "speed"
        key = (vt.prefix, kind)
        if key not in self._frames:
            survey = self.survey
            e, n = survey.components(vt)
            if e is None:
                raise WorkbenchError(f"the table has no {vt.prefix} components, speed or direction")
            X = {"position": survey.xy, "t": survey.trel}
            e = _finite_target(survey, e, f"{vt.prefix} east component")
            n = _finite_target(survey, n, f"{vt.prefix} north component")
            terms, rows = FRAME_TERMS[kind], self.hyper_rows
            self._frames[key] = tuple(
                Model(terms, max_basis=FRAME_MAX_BASIS, hyper_rows=rows).fit(X, c) for c in (e, n)
            )
        return self._frames[key]

    def secondary(self, vt: VectorTarget, primary_is_along: bool, y: np.ndarray) -> Model:
        """The baseline model of the flow-frame component a target's terms do not act on (`y`)."""
        key = (vt.prefix, primary_is_along)
        if key not in self._secondary:
            model = Model(BASELINE, hyper_rows=self.hyper_rows)
            self._secondary[key] = model.fit({"position": self.survey.xy}, y)
        return self._secondary[key]

    def frame_cv(self, vt: VectorTarget, folds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The flow frame's unit vector at each sample from the frame models refitted without its fold."""
        key = (vt.prefix, vt.aspect, np.ascontiguousarray(folds).tobytes())
        if key not in self._frame_cv:
            me, mn = self.frame(vt)
            e, n = me.cv_predict(folds)[0], mn.cv_predict(folds)[0]
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
    survey: Survey, vt: VectorTarget, xy: np.ndarray, t: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Unit vector of the smooth flow at positions `xy` and times `t` (default: mid-survey)."""
    me, mn = flow_frame(survey, vt)
    if t is None:
        t = np.full(len(xy), float(np.median(survey.trel)))
    X = {"position": xy, "t": t}
    e, n = me.predict(X), mn.predict(X)
    s = np.hypot(e, n)
    s = np.where(s > 1e-9, s, 1.0)
    return e / s, n / s


def _finite_target(survey: Survey, values: np.ndarray, what: str) -> np.ndarray:
    bad = ~np.isfinite(values)
    if bad.mean() > 0.05:
        raise WorkbenchError(f"{what} has {bad.mean():.0%} missing values")
    if bad.any():
        from forcemap.host.workbench.table import _fill_nearest_in_time

        values = _fill_nearest_in_time(values)
        note = f"filled {bad.sum()} missing value(s) of the {what} with the nearest sample in time"
        if note not in survey.notes:
            survey.notes.append(note)
    return values


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
        sog = prepare_column(survey, "sog", "covariate")
        cog = np.radians(prepare_column(survey, "cog", "covariate"))
        ce = prepare_column(survey, "current_east", "covariate")
        cn = prepare_column(survey, "current_north", "covariate")
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
    return wrap180(prepare_column(survey, "heading", "covariate") - flow)


def covariate(survey: Survey, name: str) -> np.ndarray:
    """A covariate ready for modelling: a prepared table column, or a derived one."""
    if name in survey.columns or name not in DERIVED:
        return prepare_column(survey, name, "covariate")
    values = derived_column(survey, name)
    if np.ptp(values) <= 1e-12 * max(1.0, float(np.abs(values).max())):
        raise WorkbenchError(f"covariate '{name}' is constant; there is nothing to model")
    return values


def survey_inputs(survey: Survey, names: set[str]) -> dict[str, np.ndarray]:
    X: dict[str, np.ndarray] = {"position": survey.xy, "t": survey.trel}
    for name in names - {"position", "t"}:
        X[name] = covariate(survey, name)
    return X


def grid_inputs(survey: Survey, names: set[str], xy: np.ndarray) -> dict[str, np.ndarray]:
    """Inputs for maps: depth from a depth map, time at mid-survey, every other covariate at its typical value."""
    X: dict[str, np.ndarray] = {
        "position": xy,
        "t": np.full(len(xy), float(np.median(survey.trel))),
    }
    for name in names - {"position", "t"}:
        values = survey_inputs(survey, {name})[name]
        if name == "depth":
            X[name] = survey_fits(survey).depth_map.predict({"position": xy})
        elif is_circular(name):
            X[name] = np.full(len(xy), circular_median(values))
        else:
            X[name] = np.full(len(xy), float(np.median(values)))
    return X


def hyper_rows(survey: Survey) -> np.ndarray | None:
    """Rows whose marginal likelihood sets the hyperparameters (see `SurveyFits.hyper_rows`)."""
    return survey_fits(survey).hyper_rows


class SurveyModel:
    """The model of one target on one survey: fit, cross-validate, predict on a grid."""

    def __init__(
        self,
        survey: Survey,
        target: str,
        terms: list[str] | None = None,
        max_basis: int | None = None,
    ) -> None:
        self.target, self.max_basis = target, max_basis
        terms, self.clock_offset = clock_offset.split_terms(list(terms or BASELINE))
        self.term_specs = parse_terms(terms or BASELINE, is_circular)
        self.vector = survey.vector_target(target)
        if self.clock_offset is not None:
            survey, self.clock_offset = clock_offset.corrected_for(
                survey, self.vector, self.clock_offset
            )
        self.survey = survey
        if self.vector is None:
            if target in survey.non_numeric:
                raise WorkbenchError(f"target '{target}' is not numeric")
            if target not in survey.columns or target in NOT_COVARIATES:
                raise WorkbenchError(
                    f"unknown target '{target}'; try one of: {', '.join(sorted(survey.numeric_columns()))}"
                )
            if is_circular(target):
                raise WorkbenchError(
                    f"'{target}' is an angle; angles are never regressed as scalars. "
                    "Model a vector's direction (wind_dir, current_dir) or use the angle as a covariate"
                )
        for spec in self.term_specs:
            for name in spec.inputs:
                if name == self.target or (self.vector and name in self._own_columns()):
                    raise WorkbenchError(
                        f"term {spec} uses the target's own reading '{name}' as a covariate"
                    )

    def _own_columns(self) -> set[str]:
        """The vector's own readings; a speed may depend on its own direction (shelter), so that one is allowed."""
        vt = self.vector
        aspects = (
            ("speed", "east", "north")
            if vt.aspect == "speed"
            else ("speed", "dir", "east", "north")
        )
        return {vt.name, *(vt.column(a) for a in aspects)}

    @property
    def terms(self) -> list[str]:
        out = [str(s) for s in self.term_specs]
        return (
            out if self.clock_offset is None else out + [clock_offset.describe(self.clock_offset)]
        )

    @property
    def circular(self) -> bool:
        return bool(self.vector and self.vector.aspect == "dir")

    @property
    def primary_is_along(self) -> bool:
        return bool(self.vector and self.vector.aspect == "speed")

    def _prepare_y(self) -> None:
        s, vt = self.survey, self.vector
        if vt is None:
            self.measured = prepare_column(s, self.target, "target")
            self.y_primary = self.measured
            return
        e, n = s.components(vt)
        e = _finite_target(s, e, f"{vt.prefix} east component")
        n = _finite_target(s, n, f"{vt.prefix} north component")
        if vt.aspect in ("east", "north"):
            self.measured = self.y_primary = e if vt.aspect == "east" else n
            if np.ptp(self.measured) < 1e-12:
                raise WorkbenchError(
                    f"target '{self.target}' is constant; there is nothing to model"
                )
            return
        speed = np.hypot(e, n)
        if np.ptp(speed) < 1e-12 and vt.aspect == "speed":
            raise WorkbenchError(f"target '{self.target}' is constant; there is nothing to model")
        if vt.aspect == "speed":
            self.measured = speed
        else:
            self.measured = vt.direction(e, n)
        self.ue, self.un = frame_direction(s, vt, s.xy, s.trel)
        along = e * self.ue + n * self.un
        across = -e * self.un + n * self.ue
        self.y_primary, self.y_secondary = (
            (along, across) if self.primary_is_along else (across, along)
        )

    def new_primary(
        self, terms: list | None = None, n_basis: Mapping[str, int] | None = None
    ) -> Model:
        """An unfitted model of the primary component; `n_basis` sets GP terms' bases by term name."""
        built = [build_term(t, is_circular) for t in (terms or self.term_specs)]
        for t in built:
            if isinstance(t, HilbertGPTerm) and n_basis and t.describe() in n_basis:
                t.n_basis = int(n_basis[t.describe()])
                t.max_basis = max(t.max_basis, t.n_basis)
        return Model(built, max_basis=self.max_basis, hyper_rows=hyper_rows(self.survey))

    def fit(
        self, theta: np.ndarray | None = None, n_basis: Mapping[str, int] | None = None
    ) -> SurveyModel:
        """Gather the inputs and the target (in the flow frame for a speed or direction), and fit the primary
        model; the secondary component's model is shared by every model of the survey.

        With `theta` and `n_basis` from an earlier fit of these terms on this survey (`Model.theta_`,
        `Model.n_basis_`), the primary model is rebuilt from them without the optimiser: the same map."""
        names = {i for s in self.term_specs for i in s.inputs}
        self.X = survey_inputs(self.survey, names)
        self._prepare_y()
        primary = self.new_primary(n_basis=n_basis)
        if theta is None:
            self.primary = primary.fit(self.X, self.y_primary)
        else:
            self.primary = primary.fit(self.X, self.y_primary, init=theta, optimize=False)
        if self.vector and self.vector.aspect in ("speed", "dir"):
            fits = survey_fits(self.survey)
            self.secondary = fits.secondary(self.vector, self.primary_is_along, self.y_secondary)
        else:
            self.secondary = None
        return self

    # ---- combining the primary (and secondary) Gaussian predictions into the target
    def combine(
        self, mu_p, sd_p, noise_p, mu_s=None, sd_s=None, noise_s=None, ue=None, un=None
    ) -> tuple:
        """(mean, lower95, upper95) of the target from latent means/stds of the flow-frame components."""
        if self.secondary is None:
            half = 1.96 * np.sqrt(sd_p**2 + noise_p**2)
            return mu_p, mu_p - half, mu_p + half
        rng = np.random.default_rng(12345)
        z1, z2 = rng.standard_normal((2, N_DRAWS))
        if self.primary_is_along:
            (ma, sa, na), (mc, sc, nc) = (mu_p, sd_p, noise_p), (mu_s, sd_s, noise_s)
        else:
            (ma, sa, na), (mc, sc, nc) = (mu_s, sd_s, noise_s), (mu_p, sd_p, noise_p)
        out_mean, out_lo, out_hi = np.empty(len(mu_p)), np.empty(len(mu_p)), np.empty(len(mu_p))
        ue = self.ue if ue is None else ue
        un = self.un if un is None else un
        for a0 in range(0, len(mu_p), 4096):
            sl = slice(a0, a0 + 4096)
            pa = np.sqrt(sa[sl] ** 2 + na**2)[:, None]
            pc = np.sqrt(sc[sl] ** 2 + nc**2)[:, None]
            a_lat = ma[sl, None] + sa[sl, None] * z1
            c_lat = mc[sl, None] + sc[sl, None] * z2
            a_obs = ma[sl, None] + pa * z1
            c_obs = mc[sl, None] + pc * z2
            if self.vector.aspect == "speed":
                out_mean[sl] = np.hypot(a_lat, c_lat).mean(axis=1)
                obs = np.hypot(a_obs, c_obs)
                out_lo[sl], out_hi[sl] = np.quantile(obs, [0.025, 0.975], axis=1)
            else:

                def direction(a, c, sl=sl):
                    e = a * ue[sl, None] - c * un[sl, None]
                    n = a * un[sl, None] + c * ue[sl, None]
                    return self.vector.direction(e, n)

                lat = np.radians(direction(a_lat, c_lat))
                mean = (
                    np.degrees(np.arctan2(np.sin(lat).mean(axis=1), np.cos(lat).mean(axis=1)))
                    % 360.0
                )
                dev = np.abs(wrap180(direction(a_obs, c_obs) - mean[:, None]))
                half = np.quantile(dev, 0.95, axis=1)
                out_mean[sl], out_lo[sl], out_hi[sl] = mean, mean - half, mean + half
        return out_mean, out_lo, out_hi

    def cv(self, folds: np.ndarray, primary: Model | None = None, secondary_cv=None) -> CVResult:
        """Held-out predictions of the target, weights refitted per fold (hyperparameters from the full fit)."""
        primary = primary or self.primary
        mu_p, sd_p = primary.cv_predict(folds)
        if self.secondary is None:
            mean, lo, hi = self.combine(mu_p, sd_p, primary.noise_std_)
        else:
            mu_s, sd_s = (
                secondary_cv if secondary_cv is not None else self.secondary.cv_predict(folds)
            )
            ue, un = self._frame_cv(folds)
            mean, lo, hi = self.combine(
                mu_p, sd_p, primary.noise_std_, mu_s, sd_s, self.secondary.noise_std_, ue, un
            )
        return CVResult(self.measured, mean, lo, hi, circular=self.circular)

    def _frame_cv(self, folds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The flow frame at each held-out sample from the frame models refitted without its fold: the
        full-data frame has seen the held-out vectors, and a direction target would be predicted by them."""
        return survey_fits(self.survey).frame_cv(self.vector, folds)

    def predict_grid(self, xy: np.ndarray) -> dict[str, np.ndarray]:
        """Mean and std of the target on map positions; for vectors also the east/north components."""
        names = {i for s in self.term_specs for i in s.inputs}
        X = grid_inputs(self.survey, names, xy)
        mu_p, sd_p = self.primary.predict(X, return_std=True)
        if self.secondary is None:
            return {"mean": mu_p, "std": sd_p}
        mu_s, sd_s = self.secondary.predict({"position": xy}, return_std=True)
        ue, un = frame_direction(self.survey, self.vector, xy)
        mean, lo, hi = self.combine(mu_p, sd_p, 0.0, mu_s, sd_s, 0.0, ue=ue, un=un)
        (ma, sa), (mc, sc) = (
            ((mu_p, sd_p), (mu_s, sd_s)) if self.primary_is_along else ((mu_s, sd_s), (mu_p, sd_p))
        )
        east, north = ma * ue - mc * un, ma * un + mc * ue
        spread = (hi - lo) / 3.92 if self.vector.aspect == "speed" else (hi - lo) / 2 / 1.96
        return {
            "mean": mean,
            "std": spread,
            "east": east,
            "north": north,
            "speed": np.hypot(east, north),
            "speed_std": np.sqrt(sa**2 + sc**2),
        }
