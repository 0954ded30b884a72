"""What every term is: `Term`, the base of every term kind, with the capabilities the rest of the
workbench asks of a term, and `TermSpec`, a term as written before it meets data.

A term maps its inputs to fixed features whose prior variances are set by hyperparameters (a feature
term), or is a mean function with parameters (a mean term). What a term *is* for the rest of the workbench
(a function of time, a level under depth, an oscillation along a flow axis, ...) is said once, as class
attributes of its kind; every other module asks those, never the class or the kind's name. The kinds
themselves are declared in `terms/registry.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Hyper:
    """One hyperparameter in log space, with bounds."""

    name: str
    init: float
    lo: float
    hi: float


class Term:
    """Base class. Feature terms return features and log prior variances; mean terms return a mean function.

    Capabilities (class attributes, False unless a kind says otherwise):
    `in_time`: a function of time (judged where the boat comes back; a map at another time changes).
    `predicts_in_time`: predicts beyond the survey in time (a tide's constituents, a seiche's period), where
    a smooth function of time reverts to its mean.
    `on_flow_axis`: an oscillating flow, modelled along the flow's axis (the vector's flow frame).
    `is_level`: a water level under depth (every sounding deeper by it at its time).
    `is_constant`: the model's mean level (`const`).
    `grows_basis`: a reduced-rank GP whose basis the hyperparameter search may grow.
    `acts_on_data`: not a sum term but a correction of the survey before the model (`clock_offset`).
    `estimates_period`: a spec without a period gets one from the data before the fit (`seiche`).
    `along_reference`: a vector with it is modelled along each place's reference station's flood axis
    (a tide on a reference current, `tide(reference)`).
    """

    kind = ""
    inputs: tuple[str, ...] = ()
    is_mean = False
    in_time = False
    predicts_in_time = False
    on_flow_axis = False
    is_level = False
    is_constant = False
    grows_basis = False
    acts_on_data = False
    estimates_period = False
    along_reference = False

    def hyper_index(self, name: str) -> int:
        """Position of the hyperparameter `name` in this term's slice of the parameter vector."""
        return [h.name for h in self.hypers()].index(name)

    def describe(self) -> str:
        raise NotImplementedError

    def setup(self, Z: np.ndarray) -> None:
        """Fix anything that depends on the training inputs (domain, scaling)."""

    def features(self, Z: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def hypers(self) -> list[Hyper]:
        return []

    def log_prior_var(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Log prior variance of each feature and its derivative by each log-hyperparameter (m, p)."""
        raise NotImplementedError

    def params(self, h: np.ndarray, w: np.ndarray) -> dict[str, float]:
        """Human-readable fitted parameters from hyperparameters `h` and posterior mean weights `w`."""
        return {hp.name: float(math.exp(v)) for hp, v in zip(self.hypers(), h, strict=True)}

    def periods_s(self) -> list[float]:
        """The periods (s) a fitted term oscillates at; none for a term without a period."""
        return []

    def note_at(self, h: np.ndarray, away_s: float, when: str) -> str | None:
        """What the fitted term (log-hyperparameters `h`) does at a time `away_s` outside the survey
        (`when` says it in words); None when it has nothing to say."""
        return None

    def level_features(self, t: np.ndarray, t0: float | None) -> np.ndarray:
        """A level term's features at survey times `t` (s since the survey's start at UNIX time `t0`)."""
        raise NotImplementedError(f"{self.describe()} is not a level")


@dataclass
class TermSpec:
    """A term as written by a user: kind, inputs and options, before it meets data. `text` is its
    canonical string, set by its kind's parser (`terms/registry.py`)."""

    kind: str
    inputs: tuple[str, ...]
    kernel: str = ""
    function: str = ""
    options: dict = field(default_factory=dict)
    text: str = ""

    def __str__(self) -> str:
        return self.text or self.options.get("text") or self.kind


def span_words(seconds: float) -> str:
    """A span of time in the unit a reader takes in at a glance."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    if seconds < 172800:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"
