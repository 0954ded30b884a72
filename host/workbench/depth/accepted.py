"""The soundings the depth surface accepts: one treatment of soundings for every depth map (issue 61).

`fit`, `diagnose`, `report`, `plan`, `season`, the live view and the API fit depth on the rows
`target_rows` gives (forcemap.host.workbench.survey.target_rows), and `grid` builds its surface bands
from the same soundings: the soundings the spike test and the bottom-lost test leave
(forcemap.host.workbench.survey.spikes), less those the CUBE-like surface
(forcemap.host.workbench.depth.surface) rejects. Rejected soundings stay in the table, flagged in
``spike_depth`` with their reason counted and said (a kind of their own in the depth's `Spikes`);
``--keep-outliers`` keeps them in the fit as it keeps the spikes.

The surface is built once per survey (cached with it), at nodes a cell apart: the cell is twice the
median spacing of successive soundings along the track (at least the position's sd: soundings closer
than that cannot be told apart in place). A node takes the soundings within CAPTURE (1.5) cells, so a
pass of the track gives every node it crosses about six soundings, and every sounding's nearest node
holds its neighbours on either side: a single wild reading there is outvoted by the bed around it.
grid's default 5 m cell is the map's choice, not the survey's: PacCupStart's soundings are 4.4 m apart
(a node of 5 m would hold three of a pass, and two that disagree would tie), plaka's 6.2 m.

At its nearest node a sounding is rejected when

- it is alone in a hypothesis of its own while the node holds other soundings (a single wild reading
  in a smooth ramp: where every hypothesis of a node is a single sounding, none is vouched for);
- it joined a hypothesis that fewer soundings support than the chosen one (a run of false echoes, a
  second bottom);
- it disagrees with the chosen hypothesis (the depth of its other soundings) by more than its TVU
  allows, 1.96 times the sd of the two combined: a sounding the surface cannot vouch for moves no map.

Why the fit runs on the accepted soundings rather than with a robust (Student-t) likelihood: a wild
reading is not a heavy tail of the sounder's noise but another process (a second echo, a fish, the
bottom lost for a ping), and a t-likelihood still lets it pull the map (its weight is small, not
zero), while costing an iteratively reweighted fit: 6-15 fits on bench/bench_spikes.py's surveys,
where it left maps 21-31 m off at p99 that removal left within 0.09 m (docs/WORKBENCH.md, "Spikes").
The depth target's budget (2 Gram products of a 43,500-row survey) has no room for one more fit; the
surface costs 0.1-0.3 s of CPU. On the real logs the rejection leaves 0.3-3 % of the soundings out
(docs/SOUNDINGS.md, "One depth surface", has the figures before and after).
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
