"""Which axis an oscillating flow (a tide, a seiche) is modelled along: the axis at each place or one axis
for the whole survey, chosen by the error of the held-out vector.

A vector target with a time term is split along and across its oscillation's axis (host/workbench/targets/flow_axis.py),
and both components carry the time terms. Along one fixed axis a uniform tide is one signed sinusoid in each
component, whatever the axis; along axes that turn from place to place it changes amplitude with the place,
which is right where a real stream turns with its channels and wrong where the turning comes from an
instrument's error (a yacht's leeway follows its legs). The survey says which: both frames are fitted with
the baseline plus the time terms on each component, and the one whose held-out east and north components
(blocked CV, whole spatial blocks left out, the frame itself refitted without them) are closer to the
measured ones is kept. The choice is made once per survey, vector and time terms, and every model, map and
plan of it uses the same frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from forcemap.host.workbench.validation.cv import DEFAULT_FOLDS, blocked_folds

WORDS = {True: "one axis for the survey", False: "the axis at each place"}


@dataclass(frozen=True)
class AxisChoice:
    """The frame a vector's time terms are modelled in, and the held-out errors that chose it."""

    one_axis: bool
    # held-out vector error (RMS of east and north together) with the axis at each place, and with one
    rmse_place: float
    rmse_survey: float
    samples: int
    folds: int
    # sd of the difference of the two mean squared errors, from its spread over the spatial blocks
    mse_diff_sd: float = 0.0

    @property
    def clear(self) -> bool:
        """Whether the two frames' errors differ by more than twice the sd of their difference."""
        return abs(self.rmse_place**2 - self.rmse_survey**2) > 2.0 * self.mse_diff_sd

    def line(self) -> str:
        """The choice in words, with the numbers that made it."""
        kept, other = (
            (self.rmse_survey, self.rmse_place)
            if self.one_axis
            else (self.rmse_place, self.rmse_survey)
        )
        alike = "" if self.clear else "; within the blocks' spread: the two frames predict alike"
        return (
            f"flow axis: {WORDS[self.one_axis]} (held-out vector error {kept:.4g} against {other:.4g} "
            f"with {WORDS[not self.one_axis]}; blocked {self.folds}-fold CV, {self.samples} samples{alike})"
        )

    def to_json(self) -> dict:
        return {
            "one_axis": self.one_axis,
            "rmse_place": self.rmse_place,
            "rmse_survey": self.rmse_survey,
            "mse_diff_sd": self.mse_diff_sd,
            "clear": self.clear,
            "samples": self.samples,
            "folds": self.folds,
        }


@dataclass(frozen=True)
class ReferenceAxis:
    """The frame of a tide on a reference current: each place's station's flood axis (not chosen: the
    reference gives it), with the stations the survey's rows take."""

    stations: tuple[str, ...]
    one_axis: bool = False

    def line(self) -> str:
        return (
            "flow axis: each place's reference station's flood axis (" + ", ".join(self.stations) + ")"
        )

    def to_json(self) -> dict:
        return {"one_axis": False, "reference": True, "stations": list(self.stations)}


def choose_axis(fits, vt, time_terms: tuple[str, ...]) -> AxisChoice:
    """The frame (`SurveyFits.frame_axes` at each place or for the survey) whose components, each modelled
    by the baseline plus `time_terms`, predict the held-out vector better (ties keep the axis at each place)."""
    e, n = fits.survey.components(vt)
    folds, blocks = blocked_folds(fits.survey.xy, DEFAULT_FOLDS, 0)
    sq = {}
    for one_axis in (False, True):
        ue, un = fits.frame_axes(vt, time_terms, one_axis)
        along, across = e * ue + n * un, -e * un + n * ue
        pa = fits.secondary(vt, False, along, time_terms, one_axis=one_axis)
        pc = fits.secondary(vt, True, across, time_terms, one_axis=one_axis)
        a = pa.cv_predict(folds, return_std=False)[0]
        c = pc.cv_predict(folds, return_std=False)[0]
        ve, vn = fits.frame_cv(vt, folds, time_terms, one_axis)
        de, dn = a * ve - c * vn - e, a * vn + c * ve - n
        sq[one_axis] = de**2 + dn**2
    place, survey = float(np.sqrt(sq[False].mean())), float(np.sqrt(sq[True].mean()))
    return AxisChoice(
        survey < place,
        place,
        survey,
        len(e),
        int(folds.max()) + 1,
        block_sd(sq[False] - sq[True], blocks),
    )


def block_sd(diff: np.ndarray, blocks: np.ndarray) -> float:
    """The sd of `diff`'s mean with the samples of a spatial block correlated (the cluster-robust variance
    of a mean: the blocks' totals about theirs)."""
    counts = np.bincount(blocks)
    used = counts > 0
    nb = int(used.sum())
    if nb < 2:
        return float("inf")
    dev = np.bincount(blocks, diff)[used] - counts[used] * diff.mean()
    return float(np.sqrt(nb / (nb - 1) * (dev**2).sum()) / len(diff))
