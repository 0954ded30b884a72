"""The rows that have a target: the one home every command fits a target's model on.

A model of a target (and every map, diagnosis, grid, plan and season made from it) is fitted on the rows
that have the target (a wind or current vector: both components), less the target's spikes (for depth
also the soundings the depth surface rejects, host/workbench/depth/accepted.py; unless the survey keeps
outliers), less the rows where a covariate of its terms is missing for longer than its own
correlation time (host/workbench/survey/gaps.py). Nothing is filled into a target. The rows stay in the
table: a row without current still has its depth, and the depth's model uses it. What was left out is
counted and said with its times into the survey, as the spikes are; the one refusal is too few rows
left, with how many there are.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.workbench.survey.gaps import Gaps, covariate_gaps, target_gaps, too_few
from forcemap.host.workbench.survey.reference import STALL_M_S, stalled
from forcemap.host.workbench.survey.spikes import Spikes, target_spikes
from forcemap.host.workbench.survey.table import MIN_ROWS, Survey

# inputs of a term that are no covariate column
NOT_COLUMNS = {"position", "t", "utc", "lat", "reference"}  # survey_fits.PLACE_AND_TIME


@dataclass
class TargetRows:
    """The survey a model of one target is fitted on, and what was left out of it."""

    survey: Survey
    target: str
    gaps: Gaps  # the rows without the target
    spikes: Spikes | None  # its spikes (None: left out before, on the survey given)
    covariates: tuple[str, ...] = ()  # the covariates every row has
    left: dict[str, Gaps] = field(default_factory=dict)  # rows of the target a covariate left out
    stalled: int = 0  # rows a relation to a reference current left out: the speed log stalled
    # depth: the soundings of the surface every depth map is made of (depth/accepted.py), for grid's bands
    soundings: dict | None = None
    used: np.ndarray | None = None  # bool per row of the survey given: the rows used


    @property
    def n(self) -> int:
        """The rows used."""
        return self.survey.n

    def lines(self) -> list[str]:
        """What was left out for want of a reading, and where (the spikes say their own)."""
        out = []
        if self.gaps.count:
            used = self.gaps.n - self.gaps.count
            fate = (
                "the map uses the other {used:,}"
                if self.n == used
                else f"the other {{used:,}} have it; the map uses {self.n:,} of them (the rest said below)"
            )
            out.append(self.gaps.line(fate))
        if self.stalled:
            out.append(
                f"{self.stalled:,} rows with {self.gaps.what} have the boat slower than {STALL_M_S:g} m/s "
                "through the water: a speed log reads nothing there (a berth, a stalled log), so the "
                "relation to the reference current is learned without them"
            )
        for name, g in self.left.items():
            out.append(
                f"{g.count:,} rows with {self.gaps.what} have no {name} for longer than its "
                f"correlation time ({g.where()}): left out of this model, which uses {name}"
            )
        return out

    def to_json(self) -> dict:
        return {
            "rows": self.gaps.n,
            "used": self.n,
            "missing": self.gaps.to_json(),
            "covariates": {k: g.to_json() for k, g in self.left.items()},
            "text": self.lines(),
        }


def _spike_name(survey: Survey, target: str) -> str:
    vt = survey.vector_target(target)
    return vt.prefix if vt else target


def target_flags(survey: Survey, target: str) -> Spikes | None:
    """The readings of ``target`` left out of its fits (cached with the survey): its spikes, and for
    depth the soundings the depth surface rejects, a kind of their own
    (forcemap.host.workbench.depth.accepted: every depth map fits and grids the same soundings)."""
    spikes = target_spikes(survey, target)
    if spikes is None or spikes.name != "depth":
        return spikes
    key = (TargetRows, "flags", spikes.name)
    if key not in survey.cache:
        from forcemap.host.workbench.depth.accepted import with_rejected

        survey.cache[key] = with_rejected(survey, spikes)
    return survey.cache[key]


def target_rows(survey: Survey, target: str, covariates: Iterable[str] = ()) -> TargetRows:
    """The rows of `survey` a model of `target` with these covariates is fitted on (kept with the survey:
    the speed, direction and components of one vector share them). Too few: a one-line error."""
    covariates = set(covariates)
    covs = tuple(sorted(covariates - NOT_COLUMNS))
    name = _spike_name(survey, target)
    key = (TargetRows, name, covs, "reference" in covariates)
    if key in survey.cache:
        return survey.cache[key]
    gaps = target_gaps(survey, target)
    if gaps.n - gaps.count < MIN_ROWS:
        raise too_few(gaps.n - gaps.count, gaps.what)
    drop, spikes = gaps.missing.copy(), None
    if name not in survey.spikes_removed:
        spikes = target_flags(survey, target)
        if spikes is not None and spikes.count:
            survey.columns[spikes.column] = spikes.flagged.astype(float)
            if not survey.keep_outliers:
                drop |= spikes.flagged
    left = {}
    for c in covs:
        g = covariate_gaps(survey, c)
        g.missing &= ~drop
        if g.count:
            left[c] = g
    for g in left.values():
        drop |= g.missing
    stall = stalled(survey, target) if "reference" in covariates else None
    n_stalled = 0 if stall is None else int((stall & ~drop).sum())
    if stall is not None:
        drop |= stall
    if int((~drop).sum()) < MIN_ROWS:
        have = " and ".join([gaps.what, *left]) if left else f"{gaps.what} (its spikes left out)"
        raise too_few(int((~drop).sum()), have)
    kept = spikes is not None and spikes.count > 0 and survey.keep_outliers
    # the same rows are the same survey, whatever covariates chose them: its shared fits are shared
    same = (TargetRows, name, np.packbits(drop).tobytes())
    if same not in survey.cache:
        survey.cache[same] = survey.subset(~drop) if drop.any() else survey
    rows = survey.cache[same]
    if not kept:  # checked, and left out (or clean): never looked for again on these rows
        rows.spikes_removed.add(name)
    found = survey.cache[key] = TargetRows(rows, target, gaps, spikes, covs, left, n_stalled, used=~drop)
    if spikes is not None and spikes.name == "depth":
        from forcemap.host.workbench.depth.accepted import accepted

        found.soundings = accepted(survey).soundings
    return found
