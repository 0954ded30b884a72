"""Spikes along the track: gross outliers in a target, flagged, counted, and left out of fits by default.

Hydrographic practice never maps a sounding it has not checked for spikes. The test is a Hampel filter
along the track (the table's rows in time order): each reading is compared with the running median of its
WINDOW along-track neighbours, and the departure is scaled by a robust spread (1.4826 x the median absolute
departure over a wider window, never below half the survey-wide one). A reading is a spike when it departs
by more than Z robust standard deviations *and* by more than a physical floor (FLOORS: a sounder's
false echo is metres off, a wind gust is not a spike) *and* by more than three steps of the column's
resolution (a quantised column has a MAD of zero). A running median follows steps and slopes, so a
channel edge or a sand bar wider than half the window is never a spike; a run of false echoes shorter
than half the window is.

Wind and current are tested on their east/north components together (the departure is the length of
the vector's departure), so speed, direction and components of one vector share one set of flags.

Flagged rows stay in the survey, with a `spike_<name>` column (1 = flagged), and are left out of the
model of that target unless the survey is loaded with ``keep_outliers`` (``--keep-outliers``). The
alternative, a heavy-tailed (Student-t) likelihood, was measured against removal: docs/WORKBENCH.md,
"Spikes".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from forcemap.host.fuse.bottom_lost import (
    LostStretch,
    depth_lost,
    readings_of,
    running,
    runs_of,
)
from forcemap.host.fuse.seabed import reference_on
from forcemap.host.workbench.survey.table import (
    FLAG_PREFIX,
    NOT_COVARIATES,
    Survey,
    family,
    unit_of,
)

WINDOW = 9  # along-track neighbours of the running median (odd: the reading in the middle)
SCALE_WINDOW = 61  # neighbours of the running spread
MAX_PASSES = 5
Z = 6.0
MAD_TO_STD = 1.4826
# least departure (SI) that is physically a spike, by family; depth also scales with the depth
LOST_WHY = "the bottom lost (soundings scattered more than a seabed can, no bottom under them)"
# the soundings the depth surface rejects (forcemap.host.workbench.depth.accepted)
SURFACE_WHY = "disagreeing with the depth surface (a depth most soundings around do not support)"
FLOORS = {"depth": 0.5, "current": 0.5, "wind": 8.0}  # gusts of a few m/s within seconds are wind
DEPTH_FLOOR_SHARE = 0.05


@dataclass
class Spikes:
    """The spikes of one target (a column, or a wind/current vector) on one survey."""

    name: str  # the column, or the vector's prefix ("current", "wind")
    flagged: np.ndarray  # bool, one per survey row
    departure: np.ndarray  # the reading minus the track around it (a vector's: its length)
    reference: np.ndarray  # the track around each reading (running median; a vector's: its speed)
    trel: np.ndarray  # seconds since the survey's start
    threshold: float  # the median threshold over the flagged rows (or over all rows when none is)
    kept: bool = False  # --keep-outliers: flagged, but left in the fit
    lost: np.ndarray | None = None  # depth: the rows where the bottom was lost (bottom_lost.py)
    stretches: tuple[LostStretch, ...] = ()  # ... and its stretches
    # depth: the soundings the depth surface rejects (forcemap.host.workbench.depth.accepted), what it
    # says of them and its figures
    surface: np.ndarray | None = None
    surface_line: str = ""
    surface_json: dict | None = None

    @property
    def count(self) -> int:
        return int(self.flagged.sum())

    @property
    def column(self) -> str:
        return FLAG_PREFIX + self.name

    @property
    def readings(self) -> int:
        """The rows with a reading (the others are gaps, host/workbench/survey/gaps.py)."""
        return int(np.isfinite(self.departure).sum())

    def kinds(self) -> list[tuple[int, str, np.ndarray]]:
        """(count, why, mask) for each kind of spike, most frequent first."""
        f = self.flagged
        if self.name == "depth":
            lost = self.lost if self.lost is not None else np.zeros(len(f), bool)
            surface = self.surface if self.surface is not None else np.zeros(len(f), bool)
            spike = f & ~lost & ~surface
            shallow, deep = spike & (self.departure < 0), spike & (self.departure > 0)
            out = [
                (int(lost.sum()), LOST_WHY, lost),
                (int(surface.sum()), SURFACE_WHY, surface),
                (
                    int(shallow.sum()),
                    "false shallow echoes (fish, weed, a thermocline, wake)",
                    shallow,
                ),
                (int(deep.sum()), "deep spikes (the bottom lost, or a second echo)", deep),
            ]
        else:
            out = [(int(f.sum()), "spikes (far off the readings along the track around them)", f)]
        return sorted([k for k in out if k[0]], key=lambda k: -k[0])

    def lines(self) -> list[str]:
        """What was flagged, where and why: one line per kind."""
        unit = "soundings" if self.name == "depth" else f"{self.name} readings"
        out = []
        for n, why, mask in self.kinds():
            idx = np.flatnonzero(mask)
            if why == LOST_WHY:
                out.append(self._lost_line(n, why))
                continue
            if why == SURFACE_WHY:
                out.append(self.surface_line)
                continue
            t = self.trel[idx] / 60.0
            read = self.reference[idx] + self.departure[idx] if self.name == "depth" else None
            where = f"{t.min():.0f} to {t.max():.0f} min into the survey"
            around = np.percentile(self.reference[idx], [5, 95])
            what = (
                f"; they read {np.min(read):.3g} to {np.max(read):.3g} m where the track around "
                f"reads {around[0]:.3g} to {around[1]:.3g} m"
                if read is not None
                else f"; median departure {np.median(np.abs(self.departure[idx])):.3g}"
                f"{' ' + u if (u := unit_of(self.name) or unit_of(self.name + '_speed')) else ''} from the "
                "track around"
            )
            fate = (
                "kept in the fit (--keep-outliers)"
                if self.kept
                else "left out of the fit (--keep-outliers keeps them)"
            )
            out.append(f"{n} of {self.readings} {unit} flagged as {why}, {where}{what}; {fate}")
        return out

    def _lost_line(self, n: int, why: str) -> str:
        where = ", ".join(s.text() for s in self.stretches)
        fate = (
            "kept in the fit (--keep-outliers)" if self.kept else "left out of the fit and the maps"
        )
        return (
            f"{n} of {self.readings} soundings flagged as {why}, in {len(self.stretches)} "
            f"stretch(es): {where} into the survey; {fate}"
        )

    def to_json(self) -> dict:
        return {
            "target": self.name,
            "flagged": self.count,
            "rows": len(self.flagged),
            "kept_in_fit": self.kept,
            "kinds": {why.split(" (")[0]: n for n, why, _ in self.kinds()},
            "text": self.lines(),
            "bottom_lost": [
                {"start_s": s.t0, "end_s": s.t1, "soundings": s.n, "on_seabed": s.share}
                for s in self.stretches
            ],
            "surface": self.surface_json,
        }

    def advice(self) -> str:
        if self.name == "depth":
            return (
                "filter the sounder: raise its minimum depth or gain threshold, or set its depth range "
                "to the water you survey; the flagged soundings are left out of the map"
            )
        return (
            f"check the {self.name} sensor and its cable at the times given; the flagged readings are "
            "left out of the map"
        )


def resolution(values: np.ndarray) -> float:
    """The column's step: the smallest change between successive readings that is not zero (0 if none)."""
    d = np.abs(np.diff(values[np.isfinite(values)]))
    d = d[d > 1e-9 * max(1.0, float(np.nanmax(np.abs(values))) if len(values) else 1.0)]
    return float(np.min(d)) if len(d) else 0.0


def _departure(
    parts: list[np.ndarray], masked: list[np.ndarray], fam: str | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Each reading's departure from the running median of its neighbours (`masked`: the spikes found so
    far are NaN), and that median (a vector's departure is the length of the vector of departures, and
    its reference its speed). Depth's neighbours are those left in `masked` (on the seabed's path:
    forcemap.host.fuse.seabed), and where none is, the reference is interpolated between them."""
    if fam == "depth" and len(parts) == 1:
        ref = reference_on(masked[0], WINDOW, running)
        return parts[0] - ref, ref
    meds = [running(m, WINDOW, np.nanmedian) for m in masked]
    if len(parts) == 1:
        return parts[0] - meds[0], meds[0]
    dev = np.hypot(parts[0] - meds[0], parts[1] - meds[1])
    return dev, np.hypot(meds[0], meds[1])


def find_spikes(survey: Survey, name: str, parts: list[np.ndarray], fam: str | None) -> Spikes:
    """The spikes of a target whose readings are `parts` (one column, or a vector's two components).

    The test is repeated with the spikes found so far left out of the neighbours' median, until the flags
    stop changing: a cluster of false echoes drags the median of the first pass towards it, so that some
    of them are missed and good soundings beside them look deep."""
    group = readings_of(parts)
    first = np.flatnonzero(np.diff(group, prepend=-1))
    readings = [p[first] for p in parts]
    flagged = np.zeros(len(first), bool)
    off = lost = np.zeros(len(first), bool)
    stretches: list[LostStretch] = []
    if fam == "depth" and len(parts) == 1:  # the reference from the seabed's continuous path only
        found_lost = depth_lost(parts[0], survey.trel, _xy(survey))
        stretches = found_lost.stretches
        # a row with no sounding is a gap (host/workbench/survey/gaps.py), not a sounding of the bottom lost
        lost = (found_lost.lost | _marked_lost(survey, first)) & np.isfinite(readings[0])
        if lost.any() and not stretches:  # marked by the import, on soundings since changed
            stretches = runs_of(lost, survey.trel[first])
        off = (
            ~found_lost.on_path | lost
        )  # the reference bridges a stretch from the bottom on either side
    for _ in range(MAX_PASSES):
        masked = [np.where(flagged | off, np.nan, p) for p in readings]
        found = _one_pass(name, readings, masked, fam)
        if np.array_equal(found.flagged, flagged):
            break
        flagged = found.flagged
    return Spikes(
        name,
        (found.flagged | lost)[group],
        found.departure[group],
        found.reference[group],
        survey.trel,
        found.threshold,
        survey.keep_outliers,
        lost[group] if stretches else None,
        tuple(stretches),
    )


def _xy(survey: Survey) -> np.ndarray | None:
    """The rows' positions (m), for the bottom-lost test's steepness; None where a track has none."""
    cols = getattr(survey, "columns", {})
    return survey.xy if "x" in cols and "y" in cols else None


def _marked_lost(survey: Survey, first: np.ndarray) -> np.ndarray:
    """The readings an import marked as the bottom lost (its ``bottom_lost`` column), if any."""
    marked = getattr(survey, "columns", {}).get("bottom_lost")
    if marked is None:
        return np.zeros(len(first), bool)
    return np.nan_to_num(marked[first]) > 0


def _one_pass(
    name: str, parts: list[np.ndarray], masked: list[np.ndarray], fam: str | None
) -> Spikes:
    dev, ref = _departure(parts, masked, fam)
    absdev = np.abs(dev)
    scale_of = 1.0 / 1.1774 if len(parts) == 2 else MAD_TO_STD  # Rayleigh median / Gaussian MAD
    good = np.where(np.isnan(masked[0]), np.nan, absdev)
    # depth's spread: of the soundings on the seabed (where echoes are the majority, all of them
    # would make it the echoes')
    spread_of = good if fam == "depth" and np.isfinite(good).any() else absdev
    overall = float(np.nanmedian(spread_of)) * scale_of if np.isfinite(spread_of).any() else 0.0
    local = running(good, SCALE_WINDOW, np.nanmedian) * scale_of
    spread = np.fmax(np.nan_to_num(local, nan=overall), 0.5 * overall)
    floor = FLOORS.get(fam or "", 0.0)
    if fam == "depth":
        floor = floor + DEPTH_FLOOR_SHARE * np.abs(np.nan_to_num(ref))
    step = max(resolution(p) for p in parts)
    threshold = np.fmax(np.fmax(Z * spread, floor), 3.0 * step)
    flagged = np.isfinite(absdev) & (absdev > threshold)
    thr = float(np.median(threshold[flagged] if flagged.any() else threshold))
    return Spikes(name, flagged, dev, np.nan_to_num(ref), np.zeros(0), thr)


def _name(survey: Survey, target: str) -> str:
    """What a target's spikes belong to: its vector (wind, current) or its own column."""
    vt = survey.vector_target(target)
    return vt.prefix if vt else target


def target_spikes(survey: Survey, target: str) -> Spikes | None:
    """The spikes of a model target (cached with the survey): a vector's for any aspect of wind or
    current, the column's for a scalar; None for a target the test does not apply to."""
    vt = survey.vector_target(target)
    key = (Spikes, _name(survey, target))
    if key in survey.cache:
        return survey.cache[key]
    if vt is not None:
        e, n = survey.components(vt)
        found = find_spikes(survey, vt.prefix, [e, n], vt.family)
    elif target in survey.columns and target not in NOT_COVARIATES:
        found = find_spikes(survey, target, [survey.columns[target]], family(target))
    else:
        found = None
    survey.cache[key] = found
    return found


def without_spikes(survey: Survey, target: str) -> tuple[Survey, Spikes | None]:
    """The survey the model of `target` is fitted on (one per vector: its speed, direction and components
    share it): without the target's spikes unless the survey keeps outliers; the full survey gets the
    flag column either way."""
    if _name(survey, target) in survey.spikes_removed:
        return survey, None
    found = target_spikes(survey, target)
    if found is None or not found.count:
        # checked and clean: copies made from it (a clock-corrected vector) keep these rows as they are
        survey.spikes_removed.add(_name(survey, target))
        return survey, found
    survey.columns[found.column] = found.flagged.astype(float)
    if survey.keep_outliers:
        return survey, found
    key = (Spikes, "clean", found.name)
    if key not in survey.cache:
        clean = survey.subset(~found.flagged)
        clean.spikes_removed.add(found.name)
        survey.cache[key] = clean
    return survey.cache[key], found
