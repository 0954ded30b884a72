"""Is a fitted water level the water's, or the bed's? Judged where the track comes back, held out.

A depth model with a level term (`water_level`, or a `tide`, whose uniform part is the level) fits the bed
and the level together. Only where the track comes back can a survey tell one from the other: along a single
pass a change of the level and a change of the bed look the same. Where the bed has more detail than the map
resolves (a fjord's walls under a race track), the level can take that detail along the track and swing by
metres. The soundings it was fitted to then agree as well as ever, so the check is made held out: the error
where the track revisits itself, each time stretch predicted from the others (`crossline_rmse`), with the
level and without it. A level the water has makes the passes agree better; one that took the bed's detail
makes them agree worse. Both figures are reported; nothing is judged by a threshold.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from forcemap.host.workbench.water_level import crossline_rmse, level_estimate, level_term

LEVEL_KINDS = ("water_level", "tide")


@dataclass
class LevelCheck:
    """The held-out error where the track comes back, with the model's level term and without it."""

    term: str
    samples: int
    with_level: float  # m
    without_level: float  # m
    range_m: float  # the fitted level's range over the survey

    @property
    def holds(self) -> bool:
        """Whether the level makes the passes agree at least as well as the map alone."""
        return self.with_level <= self.without_level

    def line(self) -> str:
        where = (
            f"{self.term}: where the track comes back ({self.samples} samples, each time stretch held out) "
            f"the error is {self.with_level:.3g} m with the level, {self.without_level:.3g} m without"
        )
        if self.holds:
            return f"{where}: the level (range {self.range_m:.3g} m) is the water's"
        return (
            f"{where}: the level (range {self.range_m:.3g} m) makes the passes agree less, not more. It has "
            "taken the bed's detail along the track, and this survey cannot tell its level from its bed: "
            "reduce the soundings to a gauge (--water-level GAUGE.csv), or fit without the level"
        )

    def to_json(self) -> dict:
        return asdict(self) | {"holds": self.holds}


def check_level(sm, crossline: dict | None, radius_m: float) -> LevelCheck | None:
    """The check of a fitted depth `SurveyModel` whose terms include a level, given its crossline error
    (`crossline_rmse` at `radius_m`); None when it has no level or the track comes back too little. The
    model without the level is fitted on the same survey."""
    from forcemap.host.workbench.table import family
    from forcemap.host.workbench.targets import SurveyModel

    if crossline is None or family(sm.target) != "depth" or level_term(sm.primary) is None:
        return None
    level = [str(s) for s in sm.term_specs if s.kind in LEVEL_KINDS]
    rest = [str(s) for s in sm.term_specs if s.kind not in LEVEL_KINDS]
    without = SurveyModel(sm.survey, sm.target, rest, max_basis=sm.max_basis).fit()
    other = crossline_rmse(without, radius_m)
    if other is None:
        return None
    estimate, _ = level_estimate(sm.primary, sm.survey.trel)
    return LevelCheck(
        term=" + ".join(level),
        samples=int(crossline["crossline_samples"]),
        with_level=float(crossline["crossline_rmse"]),
        without_level=float(other["crossline_rmse"]),
        range_m=float(np.ptp(estimate)),
    )
