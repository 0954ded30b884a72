"""The soundings the depth surface accepts: one treatment of soundings for every depth map (issue 61).

`fit`, `diagnose`, `report`, `plan`, `season`, the live view and the API fit depth on the rows
`target_rows` gives (forcemap.host.workbench.survey.target_rows), and `grid` builds its surface bands
from the same soundings: those the spike test and the bottom-lost test leave
(forcemap.host.workbench.survey.spikes), less those the CUBE-like surface rejects
(forcemap.host.workbench.depth.verdicts says how it judges). Rejected soundings stay in the table,
flagged in ``spike_depth`` with their reason counted and said (a kind of their own in the depth's
`Spikes`); ``--keep-outliers`` keeps them in the fit as it keeps the spikes.

The surface is judged once per survey (cached with it) on nodes a cell apart, the cell twice the median
spacing of successive soundings along the track (at least the position's sd: soundings closer than
that cannot be told apart in place). A node takes the soundings within 1.5 cells, so a pass over it
gives it about six, and every sounding's nearest node holds its neighbours on either side: a single
wild reading is outvoted by the bed around it. grid's default 5 m cell is the map's choice, not the
survey's: PacCupStart's soundings are 3.5 m apart, plaka's 6.1 m, the synthetic 43,500-row survey's 0.5 m
(a node of 5 m would hold three of a pass in plaka, and two that disagree would tie).

Why the fit runs on the accepted soundings rather than with a robust (Student-t) likelihood: a wild
reading is not a heavy tail of the sounder's noise but another process (a second echo, a fish, the
bottom lost for a ping), and a t-likelihood still lets it pull the map (its weight is small, not zero),
while costing an iteratively reweighted fit. Measured: on bench/bench_spikes.py's surveys it cost 6-15
fits and left maps 21-31 m off at p99 that removal left within 0.09 m (docs/METHODS.md, "Spikes");
on the real logs (Student-t, nu = 4, 8 reweighted fits of the rows the spike test and the import's
judgement leave) it cost 8-15 times the fit on the accepted soundings and moved the map by more than a
tenth of their disagreement at 12 % (PacCupStart) and 74 % (Flensburg 2013-07-31) of the soundings the
surface rejects. The surface costs 0.01-0.06 s on the real logs, 0.25 s on 43,500 rows. docs/SOUNDINGS.md, "One depth surface for
every map", has the figures before and after.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from forcemap.host.workbench.depth.surface import survey_soundings
from forcemap.host.workbench.depth.verdicts import ALONE, BEYOND_TVU, OUTVOTED, UNREACHED, verdicts
from forcemap.host.workbench.survey.spikes import SURFACE_WHY, Spikes
from forcemap.host.workbench.survey.table import Survey

SPACING_CELLS = 2.0  # the cell in median spacings of successive soundings along the track
MIN_SOUNDINGS = 10  # fewer soundings than this: no surface to judge them by
WHY = {
    ALONE: "alone in a depth of its own",
    OUTVOTED: "in a depth fewer soundings support",
    BEYOND_TVU: "beyond its TVU of the surface",
    UNREACHED: "at a depth the bed around cannot reach",
}


@dataclass
class Accepted:
    """The depth surface's verdict on a survey's soundings."""

    rejected: np.ndarray  # per row of the survey: a sounding the surface rejects (held rows with it)
    reason: np.ndarray  # per row: ALONE, OUTVOTED, BEYOND_TVU, or 0
    surface: np.ndarray  # per row: the chosen hypothesis's depth at its nearest node (NaN: none)
    depth: np.ndarray  # per row: the sounding
    soundings: dict  # survey_soundings' soundings every depth map uses: the accepted ones
    cell: float  # m
    trel: np.ndarray  # s since the survey's start, per row
    kept: bool = False  # --keep-outliers: rejected, but kept in the fit

    @property
    def count(self) -> int:
        return int(self.rejected.sum())

    def line(self, readings: int) -> str:
        """What the surface rejected, why and where, in one line ('' when nothing)."""
        if not self.count:
            return ""
        idx = np.flatnonzero(self.rejected)
        why = ", ".join(
            f"{n} {WHY[k]}" for k in WHY if (n := int((self.reason == k).sum()))
        )
        t = self.trel[idx] / 60.0
        fate = (
            "kept in the fit (--keep-outliers)"
            if self.kept
            else "left out of the fit and the maps (--keep-outliers keeps them)"
        )
        return (
            f"{self.count} of {readings} soundings flagged as {SURFACE_WHY}: {why} (nodes "
            f"{self.cell:.1f} m apart), {t.min():.0f} to {t.max():.0f} min into the survey; they read "
            f"{np.nanmin(self.depth[idx]):.3g} to {np.nanmax(self.depth[idx]):.3g} m where the "
            f"surface reads {np.nanmin(self.surface[idx]):.3g} to {np.nanmax(self.surface[idx]):.3g} m; {fate}"
        )

    def to_json(self) -> dict:
        return {
            "rejected": self.count,
            "cell_m": self.cell,
            "reasons": {WHY[k]: int((self.reason == k).sum()) for k in WHY},
        }


def accepted(survey: Survey) -> Accepted:
    """The surface's verdict on every sounding of ``survey`` (cached with it)."""
    key = (Accepted,)
    if key in survey.cache:
        return survey.cache[key]
    s = survey_soundings(survey)
    n = survey.n
    reason = np.zeros(len(s["depth"]), int)
    at = np.full(len(s["depth"]), np.nan)
    cell = cell_size(s)
    if len(s["depth"]) >= MIN_SOUNDINGS:
        reason, at = verdicts(s, cell)
    row = s["reading"]
    has = row >= 0
    why, surface = np.zeros(n, int), np.full(n, np.nan)
    why[has], surface[has] = reason[row[has]], at[row[has]]
    kept = survey.keep_outliers
    found = Accepted(
        why > 0, why, surface, survey.columns["depth"], s if kept else _subset(s, reason == 0),
        cell, survey.trel, kept,
    )  # fmt: skip
    survey.cache[key] = found
    return found


def with_rejected(survey: Survey, spikes: Spikes) -> Spikes:
    """The depth's spikes with the soundings the surface rejects as one kind more (flagged with them)."""
    found = accepted(survey)
    rejected = found.rejected & ~spikes.flagged  # --keep-outliers: the surface judged the spikes too
    if not rejected.any():
        return spikes
    found = replace(found, rejected=rejected, reason=np.where(rejected, found.reason, 0))
    return replace(
        spikes, flagged=spikes.flagged | rejected, surface=rejected,
        surface_line=found.line(spikes.readings), surface_json=found.to_json(),
    )  # fmt: skip


def cell_size(s: dict) -> float:
    """The nodes' spacing (m): SPACING_CELLS times the median step between successive soundings along
    the track, at least the position's sd."""
    xy = s["xy"][np.argsort(s["t"], kind="stable")]
    step = np.hypot(*np.diff(xy, axis=0).T) if len(xy) > 1 else np.zeros(0)
    spacing = float(np.median(step)) if len(step) else 0.0
    return max(SPACING_CELLS * spacing, float(s["position_sd"]), 1e-3)


def _subset(s: dict, keep: np.ndarray) -> dict:
    """The soundings ``keep`` says, with the same keys (the rows' readings renumbered)."""
    out = {k: (v[keep] if isinstance(v, np.ndarray) and k != "reading" else v) for k, v in s.items()}
    index = np.cumsum(keep) - 1
    row = s["reading"]
    ok = row >= 0
    reading = np.full(len(row), -1)
    reading[ok] = np.where(keep[row[ok]], index[row[ok]], -1)
    out["reading"] = reading
    return out
