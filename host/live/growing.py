"""A map that grows: one target's reduced-rank GP whose sufficient statistics take a rank-one update per sample.

A hyperparameter refit is `forcemap fit`'s own path (`SurveyModel(...).fit()` on the samples so far):
the map it gives is the one `forcemap fit` gives. Between refits the hyperparameters stay those of the
last refit. While the new samples lie inside the basis's box, each adds its features to the Gram
matrix (G += phi phi'), the feature-target products (b += phi y) and y'y, and the posterior is solved
again from them (O(M^3), independent of the number of samples). A sample outside the box rebuilds the
basis on all samples with the kept hyperparameters (`Component.refit(..., like=)`: `forcemap fit`'s
path without the optimiser, O(N M^2)): a Laplacian eigenbasis vanishes at its box's boundary, so a map
of samples past it is the basis's error, not the data's (measured up to 181 % of the map's range).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from forcemap.host.workbench.engine.evidence import evidence, small_blas
from forcemap.host.workbench.engine.model import Model, term_inputs
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import Survey, survey_from_columns
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms.spec import BASELINE
from scipy import linalg

GRID_CELLS = 48  # along the longer side of the survey's box
MARGIN = 0.1  # of the box, on every side
BASIS_TOL = 0.003  # a fresh fit's box this close to the live basis's: the same basis
LIVE_SOURCE = Path("<live samples>")


def _prior_logvar(model: Model) -> np.ndarray:
    """The fitted prior log variances of the weights (`Model.loglam_`)."""
    return model.loglam_


@dataclass
class Component:
    """One scalar column (depth, current_east, ...) as a growing posterior over the refit's basis."""

    column: str
    model: Model
    y_scale: float
    G: np.ndarray
    b: np.ndarray
    rr: float
    n: int

    @classmethod
    def refit(
        cls, survey: Survey, column: str, terms: list[str], like: Component | None = None
    ) -> Component:
        """`forcemap fit`'s fit of ``column`` on ``survey``: hyperparameters by marginal likelihood,
        from scratch (a warm start from the previous refit keeps a basis sized for fewer samples,
        and was measured up to half the map's range away from `forcemap fit`'s map); with ``like``,
        ``like``'s hyperparameters and number of basis functions on a basis over all of ``survey``."""
        sm = SurveyModel(survey, column, terms)
        if like is None:
            sm.fit()
        else:
            sm.fit(theta=like.model.theta_, n_basis=like.model.n_basis_)
        model, y = sm.primary, np.asarray(sm.y_primary, float)
        ys = model.y_scale_
        r = y / ys
        G = np.array(model.design_.G, copy=True)
        return cls(column, model, ys, G, model.design_.rmatvec(r), float(r @ r), len(y))

    def covers(self, xy: np.ndarray) -> bool:
        """Whether every point of ``xy`` lies inside the box the spatial basis was built on."""
        if not len(xy):
            return True
        for t in self.model.terms_:
            if t.grows_basis:
                Zr = (term_inputs(t, {"position": xy}) - t.center) @ t.rot
                if np.any(np.abs(Zr) > t.half * (1.0 + 1e-9)):
                    return False
        return True

    def same_basis(self, xy: np.ndarray, tol: float = BASIS_TOL) -> bool:
        """Whether a fresh fit on the samples ``xy`` would build this basis (its box's centre, axes and
        half-widths within ``tol``; an axis's sign does not change the basis's span). Only then is a
        rank-one update the fresh fit's map: another box gives another reduced-rank approximation
        (with a 1 % tolerance, measured up to 3 % of the map's range apart near the samples; with
        0.3 %, within 1 %: tests/test_live_maps.py)."""
        for t in self.model.terms_:
            if t.grows_basis:
                fresh = copy.deepcopy(t)
                fresh.setup(term_inputs(t, {"position": xy}))
                scale = float(t.half.max())
                if not (
                    np.allclose(fresh.center, t.center, rtol=0.0, atol=tol * scale)
                    and np.allclose(np.abs(fresh.rot), np.abs(t.rot), rtol=0.0, atol=tol)
                    and np.allclose(fresh.half, t.half, rtol=tol, atol=tol * scale)
                ):
                    return False
        return True

    def features(self, xy: np.ndarray) -> np.ndarray:
        return np.hstack(self.model.features({"position": xy}))

    def add(self, xy: np.ndarray, y: np.ndarray) -> None:
        """Rank-one updates, one per sample (as one rank-k product)."""
        ok = np.isfinite(y)
        if not ok.any():
            return
        Phi, r = self.features(xy[ok]), y[ok] / self.y_scale
        self.G += Phi.T @ Phi
        self.b += Phi.T @ r
        self.rr += float(r @ r)
        self.n += int(ok.sum())

    def predict(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean and latent standard deviation at ``xy`` from the statistics so far."""
        with small_blas():
            theta = self.model.theta_
            _, _, _, post = evidence(
                self.G, self.b, self.rr, self.n, _prior_logvar(self.model), theta[0], grad=False
            )
            Phi = self.features(xy)
            mu = Phi @ post["mu"] * self.y_scale
            V = linalg.solve_triangular(
                post["L"], (Phi * post["s"]).T, lower=True, check_finite=False
            )
            sd = np.sqrt(np.maximum((V**2).sum(axis=0), 0.0)) * self.y_scale
        return mu, sd


@dataclass
class MapGrid:
    """A live map on a regular grid in the survey's local frame (x east, y north of lat0, lon0, metres).

    ``fields`` are (ny, nx) arrays: for current and wind "east", "north", "speed" and the standard
    deviations "east_sd", "north_sd", "speed_sd" (m/s; wind FROM and current TO conventions apply to
    directions derived from them); for depth "depth" and "depth_sd" (m). This is what online planning
    reads (`forcemap.host.live.mapproc.MapBoard.latest`).
    """

    target: str
    lat0: float
    lon0: float
    x0: float
    y0: float
    step: float
    fields: dict[str, np.ndarray]
    n_samples: int
    t_fit: float  # UNIX s of the last sample in the map
    t_hyper: float  # UNIX s of the last sample of the latest hyperparameter refit
    reason: str = ""
    n_hyper: int = 0  # samples the hyperparameters were fitted on
    basis_covers: bool = True  # the basis's box holds every sample in the map
    terms: list[str] = field(default_factory=lambda: list(BASELINE))

    @property
    def shape(self) -> tuple[int, int]:
        return next(iter(self.fields.values())).shape

    @property
    def hyper_age_s(self) -> float:
        """Seconds of samples since the hyperparameters were fitted (0 right after a refit)."""
        return self.t_fit - self.t_hyper

    def age_s(self, now_s: float) -> float:
        """Seconds between the newest sample in the map and ``now_s``."""
        return now_s - self.t_fit

    @property
    def value_field(self) -> str:
        return "speed" if "speed" in self.fields else self.target

    @property
    def sd_field(self) -> str:
        return f"{self.value_field}_sd"

    def to_field(self):
        """A current or wind map as the planner's `Field` (host/plan/maps.py)."""
        from forcemap.host.plan.maps import Field

        f = self.fields
        return Field(self.x0, self.y0, self.step, f["east"], f["north"], f["east_sd"],
                     f["north_sd"], list(self.terms))  # fmt: skip


def grid_over(xy: np.ndarray) -> tuple[float, float, float, int, int]:
    """(x0, y0, step, nx, ny): a grid over the samples' box plus a margin, GRID_CELLS along its longer side."""
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    span = np.maximum(hi - lo, max(1.0, 0.25 * float(np.max(hi - lo))))
    lo, hi = lo - MARGIN * span, hi + MARGIN * span
    step = float(max(hi - lo)) / (GRID_CELLS - 1)
    nx, ny = (int(math.ceil((hi - lo)[k] / step)) + 1 for k in (0, 1))
    return float(lo[0]), float(lo[1]), step, nx, ny


def live_survey(columns: dict[str, np.ndarray], column: str | list[str]) -> Survey:
    """The rows where ``column`` (every one of a list) is known, as a survey (the workbench's checks)."""
    cols = [column] if isinstance(column, str) else column
    ok = np.ones(len(columns["t"]), bool)
    for c in cols:
        if c not in columns:
            raise WorkbenchError(f"no {c} in the samples yet")
        ok &= np.isfinite(columns[c])
    return survey_from_columns(LIVE_SOURCE, {k: v[ok] for k, v in columns.items()})
