"""A survey's reference current (`--reference-current FILE`, `read_survey(reference_current=...)`): the
file read with one clear line when it is wrong, each row's station prediction as the `reference` input of
a tide on it (`terms/reference_tide.py`), each place's station's flood axis, and which stations a survey
used, in words.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.vessel.reference_current import ReferenceCurrent, Station, read_reference
from forcemap.host.workbench.errors import WorkbenchError

INPUT = "reference"
_ROWS = "reference-rows"
# a speed log (paddle wheel) reads nothing below about this speed through the water: a current from it
# there is the boat's own ground velocity (a boat at a berth, or motoring with a stalled log)
STALL_M_S = 0.5


def load_reference(path: str | Path, station: str | None = None) -> ReferenceCurrent:
    """The reference current in `path` (harmonic constants or a predicted series), every place on
    `station` if given; a `WorkbenchError` in one line when the file or the station is wrong."""
    try:
        return read_reference(path, station)
    except ValueError as exc:
        raise WorkbenchError(f"--reference-current: {exc}") from None


def with_reference(survey, reference: ReferenceCurrent | None):  # type: ignore[no-untyped-def]
    """The survey with its reference current set (and every cached input of it dropped)."""
    survey.reference = reference
    survey.cache.pop(_ROWS, None)
    return survey


def need(survey) -> ReferenceCurrent:  # type: ignore[no-untyped-def]
    """The survey's reference current, or the one-line refusal a term on it gets without one."""
    if survey.reference is None:
        raise WorkbenchError(
            "tide(reference) needs a reference current: give --reference-current FILE (a station's "
            "harmonic constants or predicted series), or reference_current= in forcemap.read_survey"
        )
    return survey.reference


def latlon(survey, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """(lat, lon) of local positions `xy` in the survey's frame."""
    xy = np.asarray(xy, float)
    return LocalFrame(survey.lat0, survey.lon0).to_latlon(xy[:, 0], xy[:, 1])


def inputs_at(survey, xy: np.ndarray, utc: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """(n, 2): each place's station prediction along its flood axis (m/s) and its rate (m/s per s) at
    UNIX times `utc` (one, or one per place)."""
    ref = need(survey)
    lat, lon = latlon(survey, xy)
    speed, rate, _, _ = ref.at(lat, lon, np.broadcast_to(np.asarray(utc, float), (len(xy),)))
    return np.column_stack([speed, rate])


def station_vector(survey, xy: np.ndarray, utc) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """(east, north) of each place's station prediction at UNIX times `utc` (m/s)."""
    r = inputs_at(survey, xy, utc)[:, 0]
    ue, un = flood_axes(survey, xy)
    return r * ue, r * un


def survey_rows(survey) -> np.ndarray:  # type: ignore[no-untyped-def]
    """`inputs_at` the survey's own rows, computed once per survey."""
    if _ROWS not in survey.cache:
        lat, lon = survey.columns["lat"], survey.columns["lon"]
        speed, rate, _, _ = need(survey).at(lat, lon, survey.columns["t"])
        survey.cache[_ROWS] = np.column_stack([speed, rate])
    return survey.cache[_ROWS]


def flood_axes(survey, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """Unit vectors (east, north) of each place's station's flood axis."""
    lat, lon = latlon(survey, xy)
    ref = need(survey)
    idx = ref.station_index(lat, lon)
    flood = np.radians([ref.stations[ref.ids[i]].flood_dir for i in idx])
    return np.sin(flood), np.cos(flood)


def stations_used(survey, xy: np.ndarray | None = None) -> list[Station]:  # type: ignore[no-untyped-def]
    """The stations the survey's rows (or the places `xy`) take, most used first."""
    ref = need(survey)
    if xy is None:
        lat, lon = survey.columns["lat"], survey.columns["lon"]
    else:
        lat, lon = latlon(survey, xy)
    return ref.used(ref.station_index(lat, lon))


def stalled(survey, target: str) -> np.ndarray | None:  # type: ignore[no-untyped-def]
    """The rows where a current `target` from the speed log cannot be one (the boat slower through the
    water than STALL_M_S); None for another target or a table without `stw`."""
    vt = survey.vector_target(target)
    if vt is None or vt.family != "current" or "stw" not in survey.columns:
        return None
    return ~(np.nan_to_num(survey.columns["stw"], nan=np.inf) >= STALL_M_S)


def describe(survey) -> str:  # type: ignore[no-untyped-def]
    """The reference in words: the file, how places chose their station, the stations used."""
    ref = need(survey)
    how = f"station {ref.chosen} for every place" if ref.chosen else "each place's nearest station"
    used = "; ".join(s.describe() for s in stations_used(survey))
    return f"reference current {Path(ref.source).name}: {how} ({used})"
