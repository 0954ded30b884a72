"""A model of one survey target: scalar columns directly, wind and current through their vector components.

Speed and direction targets are modelled in the local flow frame: the measured vector is split into its
component along and across a smooth baseline flow direction (a GP fit of the east and north components).
Effect terms act on the along-flow component for a speed target (an effect that changes speed scales the
flow) and on the across-flow component for a direction target (one that turns the flow deflects it).
Speed and direction, and their uncertainty, are derived from the two Gaussian components by sampling.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from forcemap.host.workbench import clock_offset
from forcemap.host.workbench.cv import CVResult
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.model import Model
from forcemap.host.workbench.spec import BASELINE, build_term, parse_terms
from forcemap.host.workbench.table import Survey, VectorTarget, is_circular, prepare_column

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


def flow_frame(survey: Survey, vt: VectorTarget) -> tuple[Model, Model]:
    """Smooth models of a vector's east and north components (cached on the survey).

    For a speed target they are over position and time, so the frame follows a wind that veers and the
    along-flow component stays close to the speed. For a direction target they are over position only:
    the frame is then a reference direction that must not follow anything the diagnosis should find (with
    time in it, it followed every leg-by-leg change, a compass deviation or a veer, and the direction's
    residual had nothing left to explain). Their hyperparameters come from `hyper_rows`."""
    kind = "dir" if vt.aspect == "dir" else "speed"
    key = ("frame", vt.prefix, kind)
    if key not in survey.cache:
        e, n = survey.components(vt)
        if e is None:
            raise WorkbenchError(f"the table has no {vt.prefix} components, speed or direction")
        X = {"position": survey.xy, "t": survey.trel}
        e = _finite_target(survey, e, f"{vt.prefix} east component")
        n = _finite_target(survey, n, f"{vt.prefix} north component")
        rows = hyper_rows(survey)
        survey.cache[key] = tuple(
            Model(FRAME_TERMS[kind], max_basis=FRAME_MAX_BASIS, hyper_rows=rows).fit(X, c)
            for c in (e, n)
        )
    return survey.cache[key]


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
        survey.notes.append(
            f"filled {bad.sum()} missing value(s) of the {what} with the nearest sample in time"
        )
    return values


def derived_column(survey: Survey, name: str) -> np.ndarray:
    """Derived covariates: `heading_rel_current` / `heading_rel_wind`, the bow's angle to the baseline flow, and
    `stw`, the boat's speed through the water (ground velocity minus the measured current)."""
    if name not in survey.columns:
        if name == "stw":
            need = ("sog", "cog", "current_east", "current_north")
            missing = [c for c in need if c not in survey.columns]
            if missing:
                raise WorkbenchError(f"'stw' needs the columns {', '.join(missing)} in the table")
            sog = prepare_column(survey, "sog", "covariate")
            cog = np.radians(prepare_column(survey, "cog", "covariate"))
            ce = prepare_column(survey, "current_east", "covariate")
            cn = prepare_column(survey, "current_north", "covariate")
            survey.columns[name] = np.hypot(sog * np.sin(cog) - ce, sog * np.cos(cog) - cn)
        elif name in ("heading_rel_current", "heading_rel_wind") and "heading" in survey.columns:
            vt = survey.vector_target("current_speed" if name.endswith("current") else "wind_speed")
            if vt is None:
                raise WorkbenchError(
                    f"'{name}' needs {name.rsplit('_', 1)[1]} columns in the table"
                )
            ue, un = frame_direction(survey, vt, survey.xy, survey.trel)
            flow = np.degrees(np.arctan2(ue, un))
            if vt.is_from:
                flow = flow + 180.0
            survey.columns[name] = wrap180(prepare_column(survey, "heading", "covariate") - flow)
        else:
            survey.column(name)
    return survey.columns[name]


def survey_inputs(survey: Survey, names: set[str]) -> dict[str, np.ndarray]:
    X: dict[str, np.ndarray] = {"position": survey.xy, "t": survey.trel}
    for name in names - {"position", "t"}:
        derived_column(survey, name)
        X[name] = prepare_column(survey, name, "covariate")
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
            if ("depthmap",) not in survey.cache:
                survey.cache[("depthmap",)] = Model(BASELINE, hyper_rows=hyper_rows(survey)).fit(
                    {"position": survey.xy}, values
                )
            X[name] = survey.cache[("depthmap",)].predict({"position": xy})
        elif is_circular(name):
            X[name] = np.full(len(xy), circular_median(values))
        else:
            X[name] = np.full(len(xy), float(np.median(values)))
    return X


def hyper_rows(survey: Survey) -> np.ndarray | None:
    """Rows for the hyperparameters: the first sample of every HYPER_SPACING_S of the survey (None: all rows).

    Along a survey line the samples are a metre apart and their errors are correlated over seconds
    (paddle-wheel inertia, gusts, the sounder's 1 Hz updates, turns). Fed every sample, the marginal
    likelihood reads that as fine spatial structure: it puts the position lengthscale at the basis's
    limit, far below the line spacing, and the map then extrapolates wildly into any area it has not
    seen. Samples HYPER_SPACING_S apart are close to independent, so their marginal likelihood sets the
    hyperparameters; the posterior (the map) uses every sample."""
    if ("hyper_rows",) not in survey.cache:
        t = survey.trel
        _, rows = np.unique(np.floor((t - t.min()) / HYPER_SPACING_S), return_index=True)
        if len(rows) < MIN_HYPER_ROWS:
            rows = np.unique(
                np.linspace(0, survey.n - 1, min(MIN_HYPER_ROWS, survey.n)).astype(int)
            )
        survey.cache[("hyper_rows",)] = None if len(rows) >= survey.n else np.sort(rows)
    return survey.cache[("hyper_rows",)]


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
            if target not in survey.columns or target in ("t", "lat", "lon", "x", "y"):
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
        names = {i for s in self.term_specs for i in s.inputs}
        self.X = survey_inputs(survey, names)
        self._prepare_y()

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

    def new_primary(self, terms: list | None = None) -> Model:
        return Model(
            [build_term(t, is_circular) for t in (terms or self.term_specs)],
            max_basis=self.max_basis,
            hyper_rows=hyper_rows(self.survey),
        )

    def fit(self) -> SurveyModel:
        self.primary = self.new_primary().fit(self.X, self.y_primary)
        if self.vector and self.vector.aspect in ("speed", "dir"):
            key = ("secondary", self.vector.prefix, self.primary_is_along)
            if key not in self.survey.cache:
                self.survey.cache[key] = Model(BASELINE, hyper_rows=hyper_rows(self.survey)).fit(
                    {"position": self.survey.xy}, self.y_secondary
                )
            self.secondary = self.survey.cache[key]
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
        key = ("frame_cv", self.vector.prefix, self.vector.aspect, hash(folds.tobytes()))
        if key not in self.survey.cache:
            me, mn = flow_frame(self.survey, self.vector)
            e, n = me.cv_predict(folds)[0], mn.cv_predict(folds)[0]
            sp = np.hypot(e, n)
            sp = np.where(sp > 1e-9, sp, 1.0)
            self.survey.cache[key] = (e / sp, n / sp)
        return self.survey.cache[key]

    def fitted(self) -> np.ndarray:
        """In-sample posterior mean of the target at the samples."""
        mu_p, sd_p = self.primary.predict(self.X, return_std=True)
        if self.secondary is None:
            return mu_p
        mu_s, sd_s = self.secondary.predict({"position": self.survey.xy}, return_std=True)
        return self.combine(
            mu_p, sd_p, self.primary.noise_std_, mu_s, sd_s, self.secondary.noise_std_
        )[0]

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

    def summary_params(self) -> Mapping[str, dict[str, float]]:
        return self.primary.params_
