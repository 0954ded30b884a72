"""Clock offset between the sources of a wind or current vector: find it in a survey's table and undo it.

The daemon makes wind and current from two kinds of source: a reading in the boat's frame (apparent wind
from an anemometer, the water past the hull from paddle wheels or a speed log) and the heading and ground
velocity (a compass and a GNSS, or an autopilot). If one source's time stamps run late, the boat-frame
reading is turned by a heading from another moment: on a straight leg at steady speed nothing shows, in a
turn the vector swings with the boat. The table holds everything needed to undo it (the heading and
ground velocity are called "the autopilot's" below, whatever the boat has):

    reading in the boat frame, turned to the world:  A(t) = W(t) - V(t)       (the heading's turn included)
    re-referenced with the autopilot tau later:      W'(t) = rot(h(t + tau) - h(t)) A(t) + V(t + tau)

At tau = 0 that is the table's vector exactly. A positive tau means the autopilot's data are late.

The offset is the tau whose re-referenced vector is steadiest: the true wind and current do not turn with
the boat, so a wrong offset adds a swing at every turn, while the sensors' own noise is the same for every
tau. That is a one-dimensional scan over cheap array operations; the blocked-CV error of the corrected
target (diagnose, fit) then says whether the correction matters.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.gaps import prepare_column
from forcemap.host.workbench.survey.table import Survey, VectorTarget
from forcemap.host.workbench.terms.base import Term, TermSpec

NAME = "clock_offset"
AUTOPILOT_COLUMNS = ("heading", "sog", "cog")
# a log stamped on arrival behind a buffering link, or an instrument bus that re-sends late, can be tens
# of seconds off: the scan covers +-30 s, coarsely, then finely around the best coarse offset
MAX_OFFSET_S = 30.0
COARSE_STEP_S = 0.25
STEP_S = 0.05
# changes over this span measure the swing; the sensors' noise averages a little over it
SPAN_S = 1.0
# diagnose pairs the errors with and without the correction over stretches of track this long (a turn
# and the straightening after it)
PAIRED_STRETCH_S = 20.0


@dataclass
class OffsetScan:
    """The scan over candidate offsets: the steadiness criterion for each, and the best."""

    offsets_s: np.ndarray
    roughness: np.ndarray  # mean squared change of the vector over SPAN_S, (m/s)^2
    max_s: float = MAX_OFFSET_S

    @property
    def offset_s(self) -> float:
        return float(self.offsets_s[int(np.argmin(self.roughness))])

    @property
    def at_edge(self) -> bool:
        """The best offset is at the end of the range searched: the true one may lie beyond it."""
        return abs(self.offset_s) >= self.max_s - COARSE_STEP_S / 2

    def edge_note(self) -> str:
        if not self.at_edge:
            return ""
        return (
            f"the estimate {self.offset_s:+.2f} s is at the edge of the range searched "
            f"(+-{self.max_s:g} s): the true offset may be larger, or the vector is not steadied by any "
            "offset; check the log's time stamps"
        )

    @property
    def reduction(self) -> float:
        """Fraction of the vector's short-term change that the best offset removes."""
        at0 = float(np.interp(0.0, self.offsets_s, self.roughness))
        return 1.0 - float(self.roughness.min()) / at0 if at0 > 0 else 0.0


def applicable(survey: Survey, vt: VectorTarget | None) -> bool:
    """A clock offset can be undone for a wind or current vector when the autopilot's columns are there."""
    return vt is not None and all(c in survey.columns for c in AUTOPILOT_COLUMNS)


class ClockWork:
    """What the offset scans of one survey share: kept with the survey under this class as key."""

    def __init__(self, survey: Survey):
        self.survey = survey
        self.scans: dict[tuple[str, float, float], OffsetScan] = {}
        self.corrected: dict[tuple[str, float], Survey] = {}
        self.roughness: dict[tuple[str, float, float], float] = {}

    @functools.cached_property
    def autopilot(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Heading (unwrapped, rad) and ground velocity (east, north) at the samples, gaps filled."""
        heading, sog, cog = (
            prepare_column(self.survey, name, "heading/ground-velocity column", allow_constant=True)
            for name in AUTOPILOT_COLUMNS
        )
        c = np.radians(cog)
        return np.unwrap(np.radians(heading)), sog * np.sin(c), sog * np.cos(c)


def _work(survey: Survey) -> ClockWork:
    work = survey.cache.get(ClockWork)
    if work is None:
        work = survey.cache[ClockWork] = ClockWork(survey)
    return work


def shifted_vector(survey: Survey, vt: VectorTarget, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """The vector's (east, north) re-referenced with the autopilot's data taken tau seconds later."""
    e, n = survey.components(vt)
    if e is None or n is None:
        raise WorkbenchError(f"the table has no {vt.prefix} vector")
    ts = survey.trel
    h0, ve0, vn0 = _work(survey).autopilot
    h1, ve1, vn1 = (np.interp(ts + tau, ts, a) for a in (h0, ve0, vn0))
    ae, an = e - ve0, n - vn0
    # a compass (clockwise) rotation by d: (e, n) -> (e cos d + n sin d, -e sin d + n cos d)
    d = h1 - h0
    cd, sd = np.cos(d), np.sin(d)
    return ae * cd + an * sd + ve1, -ae * sd + an * cd + vn1


def _roughness(survey: Survey, e: np.ndarray, n: np.ndarray, max_s: float = 0.0) -> float:
    """Mean squared change of the vector over SPAN_S, over the rows every offset up to max_s can be
    taken at: near the ends, the shifted heading and velocity would be held at their first or last
    value, a vector that cannot turn, and the offset that reaches furthest past the end would look
    steadiest (on a 2.5-minute capture the scan chose -24.6 s that way)."""
    ts = survey.trel
    later = np.interp(ts + SPAN_S, ts, np.arange(len(ts)))
    j = np.minimum(np.round(later).astype(int), len(ts) - 1)
    inside = (ts >= ts[0] + max_s) & (ts + SPAN_S <= ts[-1] - max_s)
    ok = inside & (j > np.arange(len(ts))) & (np.abs(ts[j] - ts - SPAN_S) < 0.5 * SPAN_S)
    ok &= np.isfinite(e) & np.isfinite(n) & np.isfinite(e[j]) & np.isfinite(n[j])
    if ok.sum() < 10:
        raise WorkbenchError("too few evenly spaced samples to look for a clock offset")
    return float(np.mean((e[j] - e)[ok] ** 2 + (n[j] - n)[ok] ** 2))


def scan_offset(
    survey: Survey, vt: VectorTarget, max_s: float = MAX_OFFSET_S, step_s: float = STEP_S
) -> OffsetScan:
    """Roughness of the re-referenced vector for every offset in [-max_s, max_s] (a survey shorter than
    six times the range is searched over a sixth of its duration, so that two thirds of it are compared)."""
    if not applicable(survey, vt):
        raise WorkbenchError(
            "a clock offset needs a wind or current vector and the columns "
            + ", ".join(AUTOPILOT_COLUMNS)
        )
    max_s = min(max_s, max(float(np.ptp(survey.trel)) / 6.0, 2 * step_s))
    scans, key = _work(survey).scans, (vt.prefix, max_s, step_s)
    if key not in scans:
        coarse = max(step_s, min(COARSE_STEP_S, max_s / 20))
        taus = np.round(np.arange(-max_s, max_s + coarse / 2, coarse), 6)
        best = taus[int(np.argmin([_rough_at(survey, vt, t, max_s) for t in taus]))]
        fine = np.round(np.arange(best - coarse, best + coarse + step_s / 2, step_s), 6)
        taus = np.unique(np.concatenate([taus, fine[np.abs(fine) <= max_s]]))
        rough = np.array([_rough_at(survey, vt, t, max_s) for t in taus])
        scans[key] = OffsetScan(taus, rough, max_s)
    return scans[key]


def _rough_at(survey: Survey, vt: VectorTarget, tau: float, max_s: float) -> float:
    cache = _work(survey).roughness
    key = (vt.prefix, float(tau), max_s)
    if key not in cache:
        cache[key] = _roughness(survey, *shifted_vector(survey, vt, float(tau)), max_s)
    return cache[key]


def corrected_survey(survey: Survey, vt: VectorTarget, tau: float) -> Survey:
    """A copy of the survey whose vector (components, speed and direction) is re-referenced by tau."""
    e, n = shifted_vector(survey, vt, tau)
    out = survey.subset(np.ones(survey.n, bool))
    c = out.columns
    c[vt.column("east")], c[vt.column("north")] = e, n
    if vt.column("speed") in c:
        c[vt.column("speed")] = np.hypot(e, n)
    if vt.column("dir") in c:
        c[vt.column("dir")] = vt.direction(e, n)
    out.notes.append(
        f"{vt.prefix} re-referenced with the heading and ground velocity {tau:+.2f} s later"
    )
    return out


def describe(tau: float) -> str:
    """The term's name in a model's term list: the offset is part of the model."""
    return f"{NAME}({tau:+.2f} s)"


_VALUE = re.compile(r"^\s*([-+]?\d+(?:\.\d*)?)\s*s?\s*$")


class ClockOffsetTerm(Term):
    """The clock offset as a term of a wind or current model: not a sum term but a correction of the
    survey before the model, `clock_offset` to estimate it, `clock_offset(+1.50 s)` for a known value."""

    kind = NAME
    acts_on_data = True

    def __init__(self, tau: float | None) -> None:
        self.tau = math.nan if tau is None else float(tau)

    def describe(self) -> str:
        return NAME if math.isnan(self.tau) else describe(self.tau)

    def needs(self) -> set[str]:
        """The columns the correction reads beside the target's."""
        return set(AUTOPILOT_COLUMNS)

    def apply(self, survey: Survey, vt: VectorTarget | None) -> tuple[Survey, str]:
        """The survey with the vector re-referenced, and the term as the model records it."""
        corrected, tau = corrected_for(survey, vt, self.tau)
        return corrected, describe(tau)


def parse_clock_offset(args: list[str] | None, text: str, is_circular=None) -> TermSpec:
    """`clock_offset` (estimated) or `clock_offset(+1.50 s)`."""
    if args is None:
        return TermSpec(NAME, (), options={"tau": None}, text=NAME)
    m = _VALUE.match(args[0]) if len(args) == 1 else None
    if m is None:
        raise WorkbenchError(f"'{text}': write clock_offset or clock_offset(+1.50 s)")
    tau = float(m.group(1))
    return TermSpec(NAME, (), options={"tau": tau}, text=describe(tau))


def build_clock_offset(spec: TermSpec, is_circular=None) -> ClockOffsetTerm:
    return ClockOffsetTerm(spec.options.get("tau"))


def corrected_for(survey: Survey, vt: VectorTarget | None, tau: float) -> tuple[Survey, float]:
    """The survey with the vector re-referenced by tau (estimated when NaN), and tau."""
    if not applicable(survey, vt):
        raise WorkbenchError(
            f"{NAME} applies to wind and current targets, and needs the columns "
            + ", ".join(AUTOPILOT_COLUMNS)
        )
    if math.isnan(tau):
        tau = scan_offset(survey, vt).offset_s
    corrected, key = _work(survey).corrected, (vt.prefix, round(tau, 6))
    if key not in corrected:
        corrected[key] = corrected_survey(survey, vt, tau)
    return corrected[key], tau
