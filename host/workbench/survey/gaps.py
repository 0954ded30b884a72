"""Gaps in a column: the rows with no reading of a target, counted and said with their times, and a
covariate's short gaps bridged within its own correlation time.

A target is never filled: a map is fitted on the rows that have it (host/workbench/survey/target_rows.py), and
the rows without it are said as the spikes are, with their times into the survey. A covariate is an
input, not a measurement the map reproduces: where it is missing for less than its own correlation time
(the lag at which its autocorrelation along the track falls to 1/e, measured on the survey), the
nearest reading in time is still a reading of the same state, and the gap is bridged with it, with a
note. A longer gap is not bridged: the rows in it are left out of any model that uses the covariate.
Gaps are measured on every reading of the survey the rows came from (`Survey.origin`), so a subset's
gap is the table's gap, whatever other rows the subset left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.instruments import Instruments, source_name
from forcemap.host.workbench.survey.table import MIN_ROWS, Survey, is_circular

# derived covariates (host/workbench/targets/survey_fits.py) and the table columns each is computed from: a
# derived value is missing where one of them is
DERIVED_INPUTS = {
    "stw": ("sog", "cog", "current_east", "current_north"),
    "heading_rel_current": ("heading",),
    "heading_rel_wind": ("heading",),
}
# the readings a wind or current vector is made of: the one missing with it is named as the silent one
VECTOR_INPUTS = {
    "current": ("stw", "heading", "sog", "cog"),
    "wind": ("app_wind_speed", "app_wind_angle", "heading", "sog", "cog"),
}
NAMED_RUNS = 3  # the longest stretches named; the rest counted
E_FOLD = 1.0 / math.e


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) row of each run of True in `mask`, in order."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1, strict=True))


@dataclass
class Gaps:
    """The rows of a survey with no reading of one quantity (a vector: without both components)."""

    what: str  # "current", "depth", "heading", ...
    missing: np.ndarray  # bool, one per survey row
    trel: np.ndarray  # seconds since the survey's start, one per row
    who: str = ""  # the reading missing with it, when one is: "stw has no reading on 336 of them"

    @property
    def count(self) -> int:
        return int(self.missing.sum())

    @property
    def n(self) -> int:
        return len(self.missing)

    def stretches(self) -> list[tuple[float, float, int]]:
        """(start s, end s, rows) of each run of missing rows, in time order."""
        t = self.trel
        return [(float(t[a]), float(t[b]), int(b - a + 1)) for a, b in runs(self.missing)]

    def where(self) -> str:
        """The stretches by their minutes into the survey: the few longest of those longer than a typical
        gap named, the rest counted."""
        found = self.stretches()
        typical = float(np.median([s[2] for s in found])) if found else 0.0
        longer = found if len(found) <= NAMED_RUNS else [s for s in found if s[2] > typical]
        named = sorted(sorted(longer, key=lambda s: (-s[2], s[0]))[:NAMED_RUNS])
        parts = [_stretch_text(*s) for s in named]
        rest = [s for s in found if s not in named]
        if rest:
            k = sum(s[2] for s in rest)
            parts.append(
                f"{len(rest)}{' shorter' if named else ''} gap(s) ({k} rows) from "
                f"{rest[0][0] / 60:.0f} to {rest[-1][1] / 60:.0f} min"
            )
        text = " and ".join([", ".join(parts[:-1]), parts[-1]] if len(parts) > 1 else parts)
        return text + " into the survey"

    def line(self, fate: str = "the map uses the other {used:,}") -> str:
        """'612 of 11,090 rows have no current (12-19 min and 140-151 min into the survey); the map
        uses the other 10,478'."""
        who = f"; {self.who}" if self.who else ""
        used = self.n - self.count
        return (
            f"{self.count:,} of {self.n:,} rows have no {self.what} ({self.where()}{who}); "
            + fate.format(used=used)
        )

    def to_json(self) -> dict:
        return {
            "what": self.what,
            "missing": self.count,
            "rows": self.n,
            "stretches": [{"start_s": a, "end_s": b, "rows": k} for a, b, k in self.stretches()],
        }


def _stretch_text(t0: float, t1: float, rows: int) -> str:
    if t1 - t0 >= 60.0:
        return f"{t0 / 60:.0f}-{t1 / 60:.0f} min"
    return f"{t0 / 60:.1f} min ({rows} row{'s' if rows > 1 else ''})"


def too_few(rows: int, what: str) -> WorkbenchError:
    """The one refusal: too little is left to fit, and how much there is."""
    if rows == 0:
        return WorkbenchError(
            f"no row has {what}: every cell is empty, not a number or inf (a map needs at least "
            f"{MIN_ROWS} rows)"
        )
    return WorkbenchError(f"only {rows} rows have {what}; a map needs at least {MIN_ROWS}")


def target_gaps(survey: Survey, target: str) -> Gaps:
    """The rows with no reading of a model target (a wind or current vector: without both components),
    kept with the survey."""
    vt = survey.vector_target(target)
    key = (Gaps, vt.prefix if vt else target)
    if key in survey.cache:
        return survey.cache[key]
    if vt is not None:
        e, n = survey.components(vt)
        missing = ~(np.isfinite(e) & np.isfinite(n))  # type: ignore[arg-type]
        what = vt.prefix.replace("_", " ")
    else:
        missing = ~np.isfinite(survey.column(target))
        what = target
    found = Gaps(what, missing, survey.trel)
    if vt is not None and found.count:
        found.who = _silent_input(survey, missing, VECTOR_INPUTS.get(vt.family, ()))
    survey.cache[key] = found
    return found


def _silent_input(survey: Survey, missing: np.ndarray, inputs: tuple[str, ...]) -> str:
    """The reading a vector is made of that is missing on most of its gaps, named as the user knows it."""
    best, share = "", 0.0
    for c in inputs:
        if c in survey.columns:
            k = int((~np.isfinite(survey.columns[c]) & missing).sum())
            if k / max(missing.sum(), 1) > max(share, 0.5):
                best, share = c, k / missing.sum()
    if not best:
        return ""
    k = round(share * missing.sum())
    return f"{_who(survey, best)} has no reading on {k:,} of them"


def _who(survey: Survey, column: str) -> str:
    """What fed a column, by instrument: 'the speed log (GI VHW, II VHW)', or the column's name."""
    names = [source_name(x) for x in Instruments.of(survey).sources(column)]
    kinds = dict.fromkeys(n.split(" (")[0] for n in names)
    if len(kinds) != 1:
        return column
    inside = [n[n.index("(") + 1 : -1] for n in dict.fromkeys(names) if "(" in n]
    return f"{next(iter(kinds))} ({', '.join(inside)})" if inside else next(iter(kinds))


def correlation_time(t: np.ndarray, values: np.ndarray, circular: bool = False) -> float:
    """The lag (s) at which a column's autocorrelation along the track falls to 1/e (an angle's through
    its unit vector), from its readings; the survey's span if it never does."""
    ok = np.isfinite(values)
    t, v = t[ok], values[ok]
    if len(v) < 3:
        return 0.0
    rad = np.radians(v)
    parts = [np.sin(rad), np.cos(rad)] if circular else [v]
    parts = [p - p.mean() for p in parts]
    var = sum(float(np.mean(p * p)) for p in parts)
    if var <= 0.0:
        return float(t[-1] - t[0])
    n, lag, prev = len(v), 1, (0.0, 1.0)
    while lag < n // 2:
        c = sum(float(np.mean(p[:-lag] * p[lag:])) for p in parts) / var
        dt = float(np.median(t[lag:] - t[:-lag]))
        if c < E_FOLD:
            dt0, c0 = prev
            return dt0 + (c0 - E_FOLD) * (dt - dt0) / (c0 - c)
        prev, lag = (dt, c), max(lag + 1, int(lag * 1.5))
    return float(t[-1] - t[0])


@dataclass
class Bridged:
    """A covariate on every row of a survey: gaps no longer than its correlation time bridged."""

    values: np.ndarray  # NaN left in the longer gaps
    tau: float  # the correlation time (s)
    filled: int  # rows bridged
    gaps: int  # gaps bridged


def _bridge(t: np.ndarray, values: np.ndarray, tau: float) -> Bridged:
    """Each gap whose readings on either side are at most `tau` apart (at the ends of the survey: each
    row within tau/2 of the reading it takes) takes the nearest reading in time."""
    out = values.copy()
    filled = gaps = 0
    for a, b in runs(~np.isfinite(values)):
        before, after = a - 1, b + 1
        if before < 0 and after >= len(t):
            continue
        if before < 0:
            ok = 2.0 * (t[after] - t[a]) <= tau
        elif after >= len(t):
            ok = 2.0 * (t[b] - t[before]) <= tau
        else:
            ok = t[after] - t[before] <= tau
        if not ok:
            continue
        rows = np.arange(a, b + 1)
        if before < 0:
            out[rows] = values[after]
        elif after >= len(t):
            out[rows] = values[before]
        else:
            near = np.abs(t[rows] - t[before]) <= np.abs(t[after] - t[rows])
            out[rows] = np.where(near, values[before], values[after])
        filled, gaps = filled + len(rows), gaps + 1
    return Bridged(out, tau, filled, gaps)


def bridged(survey: Survey, name: str) -> np.ndarray:
    """A table column as a covariate on the survey's rows: its short gaps bridged from every reading of
    the survey of origin (said once in a note), NaN left in the longer ones."""
    values = survey.column(name)
    if np.isfinite(values).all():
        return values
    root, index = survey.origin
    if root is not survey and name in root.columns:
        if not np.array_equal(root.columns[name][index], values, equal_nan=True):
            root, index = (
                survey,
                np.arange(survey.n),
            )  # a column this survey changed (a clock offset)
    key = ("bridged", name)
    if key not in root.cache:
        values_all = root.column(name)
        tau = correlation_time(root.trel, values_all, is_circular(name))
        done = root.cache[key] = _bridge(root.trel, values_all, tau)
        if done.filled:
            note = (
                f"covariate '{name}': {done.filled} missing value(s) in {done.gaps} gap(s) no longer "
                f"than its correlation time ({done.tau:.3g} s) bridged with the nearest reading in time"
            )
            for s in (root, survey):
                if note not in s.notes:
                    s.notes.append(note)
    return root.cache[key].values[index]


def covariate_gaps(survey: Survey, name: str) -> Gaps:
    """The rows of `survey` without a covariate once its short gaps are bridged (a derived covariate:
    without one of the columns it is computed from)."""
    inputs = DERIVED_INPUTS.get(name, ()) if name not in survey.columns else (name,)
    missing = np.zeros(survey.n, bool)
    for c in inputs:
        if c in survey.columns:
            missing |= ~np.isfinite(bridged(survey, c))
    return Gaps(name, missing, survey.trel)


def prepare_column(
    survey: Survey, name: str, role: str, allow_constant: bool = False
) -> np.ndarray:
    """A column ready for modelling as a covariate: numeric, not constant, its short gaps bridged; a
    longer gap is an error here (a model chooses the rows that have its covariates first)."""
    values = survey.column(name)
    if not np.isfinite(values).any():
        raise WorkbenchError(
            f"{role} '{name}' has no values (every cell is empty, not a number or inf)"
        )
    values = bridged(survey, name)
    left = ~np.isfinite(values)
    if left.any():
        gaps = Gaps("reading", left, survey.trel)
        raise WorkbenchError(
            f"{role} '{name}': {gaps.count:,} of {gaps.n:,} rows have no reading ({gaps.where()}), in "
            "gaps longer than its correlation time; a model that uses it is fitted on the rows that have it"
        )
    if allow_constant:
        return values
    if np.ptp(values) <= 1e-12 * max(1.0, float(np.abs(values).max())):
        raise WorkbenchError(
            f"{role} '{name}' is constant ({values[0]:g}); there is nothing to model"
        )
    return values
