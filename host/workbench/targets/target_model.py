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
from forcemap.host.vessel.geodesy import wrap_from_minus180
from forcemap.host.workbench.engine.model import Model
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import NOT_COVARIATES, Survey, is_circular, why_absent
from forcemap.host.workbench.survey.target_rows import target_rows
from forcemap.host.workbench.targets import reference_part
from forcemap.host.workbench.targets.survey_fits import (
    derived_column,
    frame_direction,
    grid_inputs,
    hyper_rows,
    survey_fits,
    survey_inputs,
    terms_with_basis,
)
from forcemap.host.workbench.terms import registry, time_terms
from forcemap.host.workbench.terms.spec import BASELINE, parse_terms
from forcemap.host.workbench.validation.cv import Calibration, CVResult

N_DRAWS = 128
# the names callers have always imported from here
__all__ = ["SurveyModel", "derived_column", "hyper_rows", "survey_inputs"]


class SurveyModel:
    """The model of one target on one survey: fit, cross-validate, predict on a grid."""

    def __init__(
        self,
        survey: Survey,
        target: str,
        terms: list[str] | None = None,
        max_basis: int | None = None,
        rows_with: tuple[str, ...] = (),
    ) -> None:
        """`rows_with`: covariates outside the terms whose rows the model must be fitted on too (a
        diagnose candidate judged on the rows that have it)."""
        self.target, self.max_basis = target, max_basis
        specs = parse_terms(list(terms or BASELINE), is_circular)
        self.term_specs, data_specs = registry.split_data_terms(specs)
        self.term_specs = self.term_specs or parse_terms(BASELINE, is_circular)
        corrections = [registry.build_term(s, is_circular) for s in data_specs]
        self.vector = survey.vector_target(target)
        if survey.reference is not None and self.vector is not None and self.vector.family == "current":
            # a tide on a current with a reference is its relation to the reference
            self.term_specs = [registry.with_reference(s) for s in self.term_specs]
        self._check_target(survey)
        # the rows first (the target there, its spikes left out, every covariate there): a clock offset is
        # judged on the readings the map will be fitted to
        needs = {i for s in self.term_specs for i in s.inputs} | set(rows_with)
        for c in corrections:
            needs |= c.needs()
        self.rows = target_rows(survey, target, needs)
        survey, self.spikes, self.gaps = self.rows.survey, self.rows.spikes, self.rows.gaps
        # the terms that act on the survey before the model (a clock offset), as the model records them
        self.corrections: list[str] = []
        for c in corrections:
            survey, recorded = c.apply(survey, self.vector)
            self.corrections.append(recorded)
        self.survey = survey
        self.seiche_estimate = (
            None  # a seiche's period estimated at `fit` (host/workbench/terms/seiche.py)
        )
        # the predictive band's held-out coverage and the factor on the maps' sd (`calibrate`)
        self.calibration: Calibration | None = None
        self.cv_: CVResult | None = None  # the blocked CV `calibrate` ran, if it ran one

    def _check_target(self, survey: Survey) -> None:
        target = self.target
        if self.vector is None:
            if target in survey.non_numeric:
                raise WorkbenchError(f"target '{target}' is not numeric")
            if target not in survey.columns or target in NOT_COVARIATES:
                why = why_absent(survey.columns, target)
                what = f"no '{target}' in this table: {why}" if why else f"unknown target '{target}'"
                names = ", ".join(sorted(survey.numeric_columns()))
                raise WorkbenchError(f"{what}; try one of: {names}")
            if is_circular(target):
                raise WorkbenchError(
                    f"'{target}' is an angle; angles are never regressed as scalars. "
                    "Model a vector's direction (wind_dir, current_dir) or use the angle as a covariate"
                )
        for spec in self.term_specs:
            for name in spec.inputs:
                if name == self.target or (self.vector and name in self.own_columns()):
                    raise WorkbenchError(
                        f"term {spec} uses the target's own reading '{name}' as a covariate"
                    )

    def own_columns(self) -> set[str]:
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
        return [str(s) for s in self.term_specs] + self.corrections

    @property
    def time_terms(self) -> tuple[str, ...]:
        """The target's tide and seiche terms: they move both components of a vector."""
        return time_terms.all_terms(self.term_specs)

    @property
    def frame_terms(self) -> tuple[str, ...]:
        """The time terms of the vector's frame models (its oscillation's axis)."""
        return time_terms.frame_terms(self.term_specs)

    @property
    def axis(self):
        """The frame a vector with time terms is modelled in, and the held-out errors that chose it
        (`axis_choice.AxisChoice`); None without time terms or for a component target."""
        if not self.frame_terms or self.vector is None or self.vector.aspect not in ("speed", "dir"):
            return None
        return survey_fits(self.survey).axis(self.vector, self.frame_terms)

    @property
    def circular(self) -> bool:
        return bool(self.vector and self.vector.aspect == "dir")

    @property
    def primary_is_along(self) -> bool:
        return bool(self.vector and self.vector.aspect == "speed")

    def _prepare_y(self) -> None:
        s, vt = self.survey, self.vector
        # the station's own part where the target is modelled as its departure from it (reference_part)
        self.station_rows = reference_part.rows(self) if reference_part.applies(self) else None
        dep = 0.0 if self.station_rows is None else self.station_rows
        if vt is None:
            self.measured = self.y_primary = s.column(self.target)  # every row has it (target_rows)
            if np.ptp(self.measured) <= 1e-12 * max(1.0, float(np.abs(self.measured).max())):
                raise WorkbenchError(
                    f"target '{self.target}' is constant ({self.measured[0]:g}); there is nothing to model"
                )
            return
        e, n = s.components(vt)
        if vt.aspect in ("east", "north"):
            self.measured = e if vt.aspect == "east" else n
            self.y_primary = self.measured - dep
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
        self.ue, self.un = frame_direction(s, vt, s.xy, s.trel, self.frame_terms)
        along = e * self.ue + n * self.un - dep
        across = -e * self.un + n * self.ue
        self.y_primary, self.y_secondary = (
            (along, across) if self.primary_is_along else (across, along)
        )

    def new_primary(
        self, terms: list | None = None, n_basis: Mapping[str, int] | None = None
    ) -> Model:
        """An unfitted model of the primary component; `n_basis` sets GP terms' bases by term name."""
        built = terms_with_basis(terms or reference_part.model_terms(self), n_basis)
        return survey_fits(self.survey).model(built, max_basis=self.max_basis)

    def fit(
        self, theta: np.ndarray | None = None, n_basis: Mapping[str, int] | None = None
    ) -> SurveyModel:
        """Gather the inputs and the target (in the flow frame for a speed or direction), and fit the primary
        model; the secondary component's model is shared by every model of the survey.

        With `theta` and `n_basis` from an earlier fit of these terms on this survey (`Model.theta_`,
        `Model.n_basis_`), the primary model is rebuilt from them without the optimiser: the same map."""
        time_terms.resolve_seiche(self)
        names = {i for s in self.term_specs for i in s.inputs}
        self.X = survey_inputs(self.survey, names)
        self._prepare_y()
        reference_part.fit_relation(self)  # a relation to a reference current first: the rest is left
        primary = self.new_primary(n_basis=n_basis)
        if theta is None:
            self.primary = primary.fit(self.X, self.y_primary)
        else:
            primary.set_params(init=np.asarray(theta, float), optimize=False)
            self.primary = primary.fit(self.X, self.y_primary)
        if self.vector and self.vector.aspect in ("speed", "dir"):
            fits = survey_fits(self.survey)
            axis = self.axis
            self.secondary = fits.secondary(
                self.vector,
                self.primary_is_along,
                self.y_secondary,
                reference_part.secondary_terms(self),
                self.max_basis,
                one_axis=axis is not None and axis.one_axis,
            )
        else:
            self.secondary = None
        return self

    # ---- combining the primary (and secondary) Gaussian predictions into the target
    def combine(
        self,
        mu_p,
        sd_p,
        noise_p,
        mu_s=None,
        sd_s=None,
        noise_s=None,
        ue=None,
        un=None,
        interval: bool = True,
        spread: bool = False,
    ) -> tuple:
        """(mean, lower95, upper95) of the target from latent means/stds of the flow-frame components; without
        `interval` the bounds are NaN (for a vector the quantiles over the draws are most of the cost). With
        `spread`, a fourth: the sd of the mean alone (of the latent draws, about their mean)."""
        if self.secondary is None:
            if not interval:
                return mu_p, np.full_like(mu_p, np.nan), np.full_like(mu_p, np.nan)
            half = 1.96 * np.sqrt(sd_p**2 + noise_p**2)
            return (mu_p, mu_p - half, mu_p + half) + ((sd_p,) if spread else ())
        rng = np.random.default_rng(12345)
        z1, z2 = rng.standard_normal((2, N_DRAWS))
        if self.primary_is_along:
            (ma, sa, na), (mc, sc, nc) = (mu_p, sd_p, noise_p), (mu_s, sd_s, noise_s)
        else:
            (ma, sa, na), (mc, sc, nc) = (mu_s, sd_s, noise_s), (mu_p, sd_p, noise_p)
        ue = self.ue if ue is None else ue
        un = self.un if un is None else un
        if not (interval or spread or np.any(sa) or np.any(sc)):
            # no spread to draw from: every draw is the mean itself
            nan = np.full(len(mu_p), np.nan)
            if self.vector.aspect == "speed":
                return np.hypot(ma, mc), nan, nan
            return self.vector.direction(ma * ue - mc * un, ma * un + mc * ue), nan, nan
        out_mean, out_lo, out_hi = np.empty(len(mu_p)), np.empty(len(mu_p)), np.empty(len(mu_p))
        out_sd = np.empty(len(mu_p))
        for a0 in range(0, len(mu_p), 4096):
            sl = slice(a0, a0 + 4096)
            a_lat = ma[sl, None] + sa[sl, None] * z1
            c_lat = mc[sl, None] + sc[sl, None] * z2
            if interval:
                a_obs = ma[sl, None] + np.sqrt(sa[sl] ** 2 + na**2)[:, None] * z1
                c_obs = mc[sl, None] + np.sqrt(sc[sl] ** 2 + nc**2)[:, None] * z2
            else:
                out_lo[sl] = out_hi[sl] = np.nan
            if self.vector.aspect == "speed":
                lat_speed = np.hypot(a_lat, c_lat)
                out_mean[sl] = lat_speed.mean(axis=1)
                if spread:
                    out_sd[sl] = lat_speed.std(axis=1)
                if not interval:
                    continue
                obs = np.hypot(a_obs, c_obs)
                out_lo[sl], out_hi[sl] = np.quantile(obs, [0.025, 0.975], axis=1)
            else:

                def direction(a, c, sl=sl):
                    e = a * ue[sl, None] - c * un[sl, None]
                    n = a * un[sl, None] + c * ue[sl, None]
                    return self.vector.direction(e, n)

                lat_deg = direction(a_lat, c_lat)
                lat = np.radians(lat_deg)
                mean = (
                    np.degrees(np.arctan2(np.sin(lat).mean(axis=1), np.cos(lat).mean(axis=1)))
                    % 360.0
                )
                if spread:
                    dev = wrap_from_minus180(lat_deg - mean[:, None])
                    out_sd[sl] = np.sqrt((dev**2).mean(axis=1))
                if not interval:
                    out_mean[sl] = mean
                    continue
                dev = np.abs(wrap_from_minus180(direction(a_obs, c_obs) - mean[:, None]))
                half = np.quantile(dev, 0.95, axis=1)
                out_mean[sl], out_lo[sl], out_hi[sl] = mean, mean - half, mean + half
        return (out_mean, out_lo, out_hi) + ((out_sd,) if spread else ())

    def cv(
        self,
        folds: np.ndarray,
        primary: Model | None = None,
        secondary_cv=None,
        interval: bool = True,
    ) -> CVResult:
        """Held-out predictions of the target, weights refitted per fold (hyperparameters from the full fit).

        Without `interval`, no 95 % bounds (NaN), and both components' latent spreads are left out of a
        speed's or direction's mean: a spread moves that mean only at second order (times the squared share
        of the other component), and its triangular solves are half the cost of a fold. The diagnosis
        compares errors only, of models treated alike (`secondary_cv` is then given without its spread)."""
        primary = primary or self.primary
        mu_p, sd_p = primary.cv_predict(folds, return_std=interval)
        if sd_p is None:
            sd_p = np.zeros_like(mu_p)
        if self.secondary is None:
            mu_p, _ = reference_part.add_along(self, mu_p, None, reference_part.cv_part(self, folds))
            mean, lo, hi = self.combine(mu_p, sd_p, primary.noise_std_, interval=interval)
        else:
            mu_s, sd_s = (
                secondary_cv
                if secondary_cv is not None
                else self.secondary.cv_predict(folds, return_std=interval)
            )
            if sd_s is None:
                sd_s = np.zeros_like(mu_s)
            mu_p, mu_s = reference_part.add_along(self, mu_p, mu_s, reference_part.cv_part(self, folds))
            ue, un = self._frame_cv(folds)
            mean, lo, hi = self.combine(
                mu_p,
                sd_p,
                primary.noise_std_,
                mu_s,
                sd_s,
                self.secondary.noise_std_,
                ue,
                un,
                interval=interval,
            )
        return CVResult(self.measured, mean, lo, hi, circular=self.circular)

    def calibrate(self, folds: np.ndarray, cv: CVResult | None = None) -> CVResult:
        """Cross-validate on `folds` (or take `cv`, done on them) and keep the `Calibration` of the predictive
        band: the maps' sd is then the predictive sd times its factor. Returns the CV."""
        cv = self.cv(folds) if cv is None else cv
        self.calibration = Calibration.of(cv, folds, self.survey.xy)
        self.cv_ = cv
        return cv

    @property
    def sd_scale(self) -> float:
        return self.calibration.sd_scale if self.calibration is not None else 1.0

    @property
    def signal_sd(self) -> float:
        """The measured target's own spread (deg about its circular mean for a direction)."""
        if not hasattr(self, "measured"):
            self._prepare_y()
        m = self.measured
        if self.circular:
            r = np.radians(m)
            mean = np.degrees(np.arctan2(np.sin(r).mean(), np.cos(r).mean()))
            return float(np.sqrt(np.mean(wrap_from_minus180(m - mean) ** 2)))
        return float(np.std(m))

    def _frame_cv(self, folds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The flow frame at each held-out sample from the frame models refitted without its fold: the
        full-data frame has seen the held-out vectors, and a direction target would be predicted by them."""
        return survey_fits(self.survey).frame_cv(self.vector, folds, self.frame_terms)

    def predict_grid(
        self, xy: np.ndarray, at: float | np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        """Mean and predictive std of the target on map positions (what a new measurement there would differ
        from the mean by: latent plus noise variance, times the calibration's `sd_scale`), and `mean_std`, the
        sd of the mean alone; for vectors also the east/north components and their predictive stds. At UNIX
        time `at` (one, or one per position; default mid-survey)."""
        names = {i for s in self.term_specs for i in s.inputs}
        X = grid_inputs(self.survey, names, xy, at)
        k = self.sd_scale
        mu_p, sd_p = self.primary.predict(X, return_std=True)
        noise_p = self.primary.noise_std_
        station = reference_part.part(self, xy, X)
        if self.secondary is None:
            mu_p, _ = reference_part.add_along(self, mu_p, None, station)
            return {"mean": mu_p, "std": k * np.hypot(sd_p, noise_p), "mean_std": sd_p}
        mu_s, sd_s = self.secondary.predict(X, return_std=True)
        mu_p, mu_s = reference_part.add_along(self, mu_p, mu_s, station)
        noise_s = self.secondary.noise_std_
        ue, un = frame_direction(self.survey, self.vector, xy, X["t"], self.frame_terms)
        mean, lo, hi, mean_std = self.combine(
            mu_p, sd_p, noise_p, mu_s, sd_s, noise_s, ue=ue, un=un, spread=True
        )
        (ma, sa, na), (mc, sc, nc) = (
            ((mu_p, sd_p, noise_p), (mu_s, sd_s, noise_s))
            if self.primary_is_along
            else ((mu_s, sd_s, noise_s), (mu_p, sd_p, noise_p))
        )
        pa, pc = np.hypot(sa, na), np.hypot(sc, nc)  # a new measurement's along and across spread
        east, north = ma * ue - mc * un, ma * un + mc * ue
        spread = (hi - lo) / 3.92 if self.vector.aspect == "speed" else (hi - lo) / 2 / 1.96
        return {
            "mean": mean,
            "std": k * spread,
            "mean_std": mean_std,
            "east": east,
            "north": north,
            "speed": np.hypot(east, north),
            "speed_std": k * np.hypot(pa, pc),
            # the along and across components are independent: rotate their variances
            "east_std": k * np.hypot(pa * ue, pc * un),
            "north_std": k * np.hypot(pa * un, pc * ue),
        }
