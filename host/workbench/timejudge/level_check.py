"""Is a fitted water level the water's, or the bed's? Judged where the track comes back, held out.

A depth model with a level term (`water_level`, or a `tide`, whose uniform part is the level) fits the bed
and the level together. Only where the track comes back can a survey tell one from the other: along a single
pass a change of the level and a change of the bed look the same. Where the bed has more detail than the map
resolves (a fjord's walls under a race track), the level can take that detail along the track and swing by
metres. The soundings it was fitted to then agree as well as ever, so the check is made held out: the error
where the track revisits itself, each time stretch predicted from the others (`water_level.crossline_errors`),
with the level and without it. A level the water has makes the passes agree better; one that took the
bed's detail makes them agree worse. The two are compared sample by sample, the time stretches of the
crossline folds the independent units: a difference within twice its sd over them is no difference.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from forcemap.host.progress import note
from forcemap.host.workbench.depth.water_level import crossline_errors, level_estimate, level_term
from forcemap.host.workbench.survey.table import family
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms import registry
from forcemap.host.workbench.validation.cv import clustered_sd


@dataclass
class LevelCheck:
    """The held-out error where the track comes back, with the model's level term and without it, and
    the sd of their difference in mean square, the time stretches its independent units."""

    term: str
    samples: int
    with_level: float  # m, RMSE
    without_level: float  # m, RMSE
    sd_difference: float  # m^2: the sd of the difference of the two mean squares
    range_m: float  # the fitted level's range over the survey

    @property
    def difference(self) -> float:
        """The mean square without the level less the one with it (m^2): positive where the level helps."""
        return self.without_level**2 - self.with_level**2

    @property
    def verdict(self) -> str:
        """"water" (the level makes the passes agree better), "bed" (worse), or "alike"."""
        if abs(self.difference) <= 2.0 * self.sd_difference:
            return "alike"
        return "water" if self.difference > 0 else "bed"

    def line(self) -> str:
        where = (
            f"{self.term}: where the track comes back ({self.samples} samples, each time stretch held out) "
            f"the error is {self.with_level:.3g} m with the level, {self.without_level:.3g} m without"
        )
        if self.verdict == "water":
            return f"{where}: the level (range {self.range_m:.3g} m) is the water's"
        if self.verdict == "alike" and self.difference > 0:
            return (
                f"{where}, better by {self.difference / self.sd_difference:.1f} sd of the difference over "
                f"the time stretches, short of the 2 that would settle it: the level (range "
                f"{self.range_m:.3g} m) makes the passes agree better, but the crossings cannot yet tell it "
                "from none; a gauge settles it (--water-level GAUGE.csv)"
            )
        if self.verdict == "alike":
            return (
                f"{where}, alike within twice the sd over the time stretches: the crossings cannot tell this "
                f"level (range {self.range_m:.3g} m) from none; keep the map without it, or reduce the "
                "soundings to a gauge (--water-level GAUGE.csv)"
            )
        return (
            f"{where}: the level (range {self.range_m:.3g} m) makes the passes agree less, not more. It has "
            "taken the bed's detail along the track, and this survey cannot tell its level from its bed: "
            "reduce the soundings to a gauge (--water-level GAUGE.csv), or fit without the level"
        )

    def to_json(self) -> dict:
        return asdict(self) | {"verdict": self.verdict}


def check_level(sm, radius_m: float, errors, progress: bool = False) -> LevelCheck | None:
    """The check of a fitted depth `SurveyModel` whose terms include a level, given its `crossline_errors`
    within `radius_m`; None when it has no level or the track comes back too little. The model without the
    level is fitted on the same survey."""
    if errors is None or family(sm.target) != "depth" or level_term(sm.primary) is None:
        return None
    note("checking the level against the map alone where the track comes back ...", progress)
    level = [str(s) for s in sm.term_specs if registry.caps(s).is_level]
    rest = [str(s) for s in sm.term_specs if not registry.caps(s).is_level]
    without = SurveyModel(sm.survey, sm.target, rest, max_basis=sm.max_basis).fit()
    e1 = errors[0] ** 2
    e0 = crossline_errors(without, radius_m)[0] ** 2  # the same survey: the same folds and rows
    estimate, _ = level_estimate(sm.primary, sm.survey.trel)
    return LevelCheck(
        term=" + ".join(level),
        samples=len(e1),
        with_level=float(np.sqrt(np.mean(e1))),
        without_level=float(np.sqrt(np.mean(e0))),
        sd_difference=clustered_sd(e0 - e1, errors[1]),
        range_m=float(np.ptp(estimate)),
    )
