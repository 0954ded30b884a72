"""The Python API (`import forcemap`): read a survey, fit a target, grid it, write it for GIS.

Thin on purpose: each call is the code a command runs (`load_survey`, `fit_target`, `diagnose`, the
workspace's latest-fit rule of `report` and `plan`, `host.gis`). `Fit` follows scikit-learn's conventions:
`__init__` stores its arguments, `fit(survey)` returns the fit, fitted state ends in `_` (`cv_rmse` and
the other summaries are read-only views of it).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.at_time import parse_at
from forcemap.host.workbench.survey.table import Survey as _Table
from forcemap.host.workbench.terms.spec import BASELINE, check_terms, split_effects

DEFAULT_RESOLUTION_M = 5.0


def read_survey(
    path: str | Path | Sequence[str | Path],
    keep_outliers: bool = False,
    water_level: str | Path | None = None,
    reference_current: str | Path | None = None,
    reference_station: str | None = None,
) -> Survey:
    """A samples table (CSV, Parquet, or an MCAP log from `forcemap run`), or a list of them (days of
    the same water as one survey, kept in the first one's workspace), validated, as a `Survey`; with
    `keep_outliers`, the spikes flagged along the track stay in the fits (`--keep-outliers`); with
    `water_level` (a gauge's CSV), the depth is reduced to the gauge's datum (`--water-level`); with
    `reference_current` (stations' harmonic constants or a predicted series), a tide on the current is
    each place's relation to its nearest station, or to `reference_station` (`--reference-current`)."""
    from forcemap.host.workbench.survey.reference import load_reference, with_reference
    from forcemap.host.workbench.survey.several import load_surveys

    paths = path if isinstance(path, str | Path) else list(path)
    table = load_surveys(paths, keep_outliers=keep_outliers)
    if reference_station is not None and reference_current is None:
        raise WorkbenchError("reference_station needs reference_current")
    if reference_current is not None:
        with_reference(table, load_reference(reference_current, reference_station))
    if water_level is not None:
        from forcemap.host.workbench.depth.water_level import read_gauge, reduce_to_gauge

        table = reduce_to_gauge(table, read_gauge(water_level))
    return Survey(table)


class Survey:
    """A survey: its samples in SI units (`table`, the workbench's `Survey`) and its workspace beside it."""

    def __init__(self, table: _Table) -> None:
        self.table = table

    @property
    def path(self) -> Path:
        return Path(self.table.source)

    @property
    def n(self) -> int:
        return self.table.n

    @property
    def columns(self) -> list[str]:
        return list(self.table.columns)

    @property
    def notes(self) -> list[str]:
        return list(self.table.notes)

    def __repr__(self) -> str:
        return f"Survey({str(self.path)!r}, n={self.n})"

    def fit(
        self,
        target: str,
        effects: Iterable[str] | str = (),
        terms: Sequence[str] | None = None,
        folds: str = "blocked",
        record: bool = False,
        progress: bool = False,
    ) -> Fit:
        """Fit `target` with the baseline plus `effects` (or exactly `terms`); `record` saves it in the
        workspace as `forcemap fit` does."""
        return Fit(target, effects, terms, folds).fit(self, record=record, progress=progress)

    def latest_fit(self, target: str, progress: bool = False) -> Fit:
        """The workspace's latest fit of `target` (the rule of `report` and `plan`): its terms, rebuilt
        from its saved hyperparameters when they fit this table; the baseline if there is no fit."""
        from forcemap.host.workbench.fits.fit import calibrated, map_terms, refit_or_restore
        from forcemap.host.workbench.fits.workspace import load_history, workspace_dir

        ws = workspace_dir(self.path, create=False)
        history = load_history(ws) if ws.is_dir() else []
        terms = map_terms(self.table, history, target)
        check_terms(terms)
        fit = Fit(target, terms=terms)
        fit.model_ = calibrated(refit_or_restore(ws, history, self.table, target, terms, progress))
        fit.survey_, fit.result_ = self, None
        return fit

    def grid(
        self,
        fits: Iterable[Fit],
        resolution: float = DEFAULT_RESOLUTION_M,
        max_distance: float | None = None,
        at: str | float | None = None,
    ):
        """The fits' maps on one grid in the survey's UTM zone (`host.gis.grid.MapGrid`), at time `at`
        (`--at`'s forms: ISO 8601 with its zone, UNIX seconds, "now"; default the survey's mid-time)."""
        from forcemap.host.gis import need_gis
        from forcemap.host.gis.grid import evaluate, make_grid

        need_gis()
        fits = list(fits)
        prefixes = [f.model_.vector.prefix for f in fits if f.model_.secondary is not None]
        if len(set(prefixes)) < len(prefixes):
            raise WorkbenchError(
                "two targets map the same vector (say current_speed and current_dir); give one of them"
            )
        grid = make_grid(self.table, resolution, max_distance)
        grid.at = None if at is None else parse_at(at)
        # one target per core: the work is in numpy and BLAS, which release the GIL
        workers = max(1, min(len(fits), os.cpu_count() or 1))
        with ThreadPoolExecutor(workers) as pool:
            layers = list(pool.map(lambda f: evaluate(grid, f.model_), fits))
        grid.layers = {f.target: layer for f, layer in zip(fits, layers, strict=True)}
        grid.notes += [n for layer in layers for n in layer.notes]
        return grid


class Fit:
    """A model of one target on one survey: `Fit(target, effects).fit(survey)`."""

    def __init__(
        self,
        target: str,
        effects: Iterable[str] | str = (),
        terms: Sequence[str] | None = None,
        folds: str = "blocked",
    ) -> None:
        self.target = target
        self.effects = effects
        self.terms = terms
        self.folds = folds

    def get_params(self, deep: bool = True) -> dict:
        return {k: getattr(self, k) for k in ("target", "effects", "terms", "folds")}

    def _terms(self) -> list[str]:
        if self.terms is not None:
            return list(self.terms)
        effects = split_effects(self.effects) if isinstance(self.effects, str) else self.effects
        return list(BASELINE) + [e for e in effects if e not in BASELINE]

    def fit(self, survey: Survey, record: bool = False, progress: bool = False) -> Fit:
        """Fit and cross-validate (spatially blocked folds) on `survey`; returns self."""
        from forcemap.host.workbench.engine.model import small_blas
        from forcemap.host.workbench.fits import fit as fitting

        terms = self._terms()
        check_terms(terms)
        with small_blas():
            self.result_ = fitting.fit_target(
                survey.table, self.target, terms, self.folds, progress
            )
        self.model_, self.survey_ = self.result_.model, survey
        self.entry_ = fitting.record(survey.path, self.result_) if record else None
        return self

    def _fitted(self):
        if not hasattr(self, "model_"):
            from forcemap.host.workbench.engine.model import NotFittedError

            raise NotFittedError("this Fit is not fitted yet: call fit(survey) first")
        return self.model_

    def _cv(self):
        self._fitted()
        if self.result_ is None:  # restored from the workspace: cross-validate on first use, once
            from forcemap.host.workbench.fits.fit import make_folds

            if getattr(self, "cv_", None) is None:
                done = self.model_.cv_ if self.folds == "blocked" else None  # its calibration's CV
                self.cv_ = done or self.model_.cv(make_folds(self.model_.survey, self.folds))
            return self.cv_
        return self.result_.cv

    @property
    def cv_rmse(self) -> float:
        """Cross-validated RMSE (blocked folds)."""
        return float(self._cv().rmse)

    @property
    def cv_mae(self) -> float:
        return float(self._cv().mae)

    @property
    def coverage95(self) -> float:
        """The share of held-out samples inside the model's own predictive 95 % band."""
        return float(self._cv().coverage95)

    @property
    def n_rows(self) -> int:
        """The rows the model is fitted on: those that have the target (a vector: both components), less
        its spikes and the rows a covariate of its terms lacks for longer than its correlation time."""
        return self._fitted().survey.n

    @property
    def left_out(self) -> list[str]:
        """What the fit left out, and where, in words: rows without the target or a covariate, spikes."""
        model = self._fitted()
        return model.rows.lines() + (model.spikes.lines() if model.spikes else [])

    @property
    def calibration(self):
        """The predictive band's `Calibration`: its held-out coverage once scaled (`coverage`), the factor on
        the maps' sd (`sd_scale`), the model's own coverage, and how far from the track the CV reached."""
        from forcemap.host.workbench.fits.fit import calibrated

        return calibrated(self._fitted()).calibration

    def __repr__(self) -> str:
        terms = " + ".join(self.model_.terms) if hasattr(self, "model_") else "not fitted"
        return f"Fit({self.target!r}: {terms})"

    def predict(self, lat, lon, at=None) -> dict[str, np.ndarray]:
        """The model at positions (degrees) and time `at` (one for all, or one per position: `--at`'s forms,
        ISO 8601 with its zone, UNIX seconds or "now"; default the survey's mid-time): `mean`, `std` the
        predictive sd (what a new measurement there would differ by: latent plus noise, scaled by the
        calibration), `mean_std` the sd of the mean alone (and east/north/speed with their predictive sds
        for a vector)."""
        from forcemap.host.vessel.geodesy import LocalFrame

        model = self._fitted()
        s = model.survey
        x, y = LocalFrame(s.lat0, s.lon0).to_local(np.atleast_1d(lat), np.atleast_1d(lon))
        when = None
        if at is not None:
            when = parse_at(at) if np.ndim(at) == 0 else np.array([parse_at(v) for v in at])
        return model.predict_grid(np.column_stack([x, y]), when)

    def notes_at(self, at) -> list[str]:
        """What the model's time terms do at `at`: a tide predicts, a GP in time reverts to its mean
        beyond its lengthscale from the survey (empty inside the survey's span)."""
        from forcemap.host.workbench.terms.time_terms import notes_at

        model = self._fitted()
        return notes_at(model.primary, model.survey, parse_at(at))

    def tide(self) -> dict:
        """The fitted tide and seiche: each constituent's amplitude and Greenwich phase with their sd
        (`constituents`), a vector's tidal ellipses (`ellipses`) and the axis its components are modelled
        along (`axis`, host/workbench/targets/axis_choice.py), a seiche's estimated period (`seiche`)."""
        from forcemap.host.workbench.terms.time_terms import tide_summary

        return tide_summary(self._fitted())

    def relation(self, lat, lon) -> dict[str, np.ndarray]:
        """With a reference current: each position's relation to its station (`station`), the flood's
        `ratio`, `offset_s` (the place later than its station by it) and `turn_deg` (its flood's angle
        from the station's axis, clockwise), the ebb's (`ebb_*`), each with its sd (`*_sd`)."""
        from forcemap.host.vessel.geodesy import LocalFrame
        from forcemap.host.workbench.terms.time_terms import relation_at

        model = self._fitted()
        s = model.survey
        x, y = LocalFrame(s.lat0, s.lon0).to_local(np.atleast_1d(lat), np.atleast_1d(lon))
        return relation_at(model, np.column_stack([x, y]))

    def diagnose(self, rounds: int = 1, progress: bool = False):
        """Which physical effect this model is missing (`forcemap diagnose`): a `Diagnosis`."""
        from forcemap.host.workbench.diagnose.rounds import diagnose
        from forcemap.host.workbench.engine.model import small_blas

        model = self._fitted()
        with small_blas():
            return diagnose(self.survey_.table, self.target, model.terms, rounds, progress=progress)

    def grid(
        self,
        resolution: float = DEFAULT_RESOLUTION_M,
        max_distance: float | None = None,
        at: str | float | None = None,
    ):
        """This fit's map on a grid in the survey's UTM zone (`MapGrid`), at time `at` (default mid-survey)."""
        self._fitted()
        return self.survey_.grid([self], resolution, max_distance, at)

    def to_xarray(
        self,
        resolution: float = DEFAULT_RESOLUTION_M,
        max_distance: float | None = None,
        at: str | float | None = None,
    ):
        """The map as a CF-1.8 `xarray.Dataset` (what `forcemap grid -o maps.nc` writes), at time `at`."""
        from forcemap.host.gis.netcdf import to_dataset

        return to_dataset(self.grid(resolution, max_distance, at))

    def to_geotiff(
        self,
        path: str | Path,
        resolution: float = DEFAULT_RESOLUTION_M,
        force: bool = False,
        at: str | float | None = None,
    ) -> Path:
        """Write the map as a Cloud Optimized GeoTIFF (an existing file only with `force`), at time `at`."""
        from forcemap.host.gis.geotiff import write_geotiff
        from forcemap.host.outputs import check_output

        out = check_output(path, [self.survey_.path], force=force)
        grid = self.grid(resolution, at=at)
        return write_geotiff(grid, grid.layers[self.target], out)
