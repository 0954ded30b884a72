"""The reference station's own part of a current modelled on a reference: the model fits the departure.

A tide on a reference current (`terms/reference_tide.py`) relates each place to its station, and the
station's prediction is the relation's natural start: ratio 1, no offset, the flood along the station's
axis. So a vector whose terms put it along its stations' flood axes is modelled as its departure from
the station's prediction (the along component less the prediction r(t); a scalar east or north
component less r(t) times the flood axis's east or north), and the prediction is added back wherever
the components are combined into the vector. Every weight of the term is then a departure from the
station with a zero-mean prior: where a day's data cannot tell a mean flow from a ratio (a single flood),
the fit stays with the station instead of trading one for the other, and the relation is the station's
plus the fitted departure (`terms/reference_maps.py` adds the 1 back).
"""

from __future__ import annotations

import numpy as np
from forcemap.host.workbench.survey import reference
from forcemap.host.workbench.targets.flow_axis import along_reference


def applies(sm) -> bool:
    """Whether the `SurveyModel`'s target is modelled as its departure from its stations."""
    return (
        sm.vector is not None
        and sm.survey.reference is not None
        and along_reference(sm.time_terms)
    )


def part(sm, xy: np.ndarray, utc: np.ndarray) -> np.ndarray:
    """The station's prediction on the model's along component (speed, direction) or on its own
    component (east, north) at places `xy` and UNIX times `utc`."""
    r = reference.inputs_at(sm.survey, xy, utc)[:, 0]
    return _project(sm, xy, r)


def rows(sm) -> np.ndarray:
    """`part` at the survey's own rows (computed once per survey)."""
    return _project(sm, sm.survey.xy, reference.survey_rows(sm.survey)[:, 0])


def _project(sm, xy: np.ndarray, r: np.ndarray) -> np.ndarray:
    aspect = sm.vector.aspect
    if aspect in ("speed", "dir"):
        return r
    ue, un = reference.flood_axes(sm.survey, xy)
    return r * (ue if aspect == "east" else un)


def add_along(sm, mu_p: np.ndarray, mu_s, station: np.ndarray | None):
    """The primary and secondary means with the station's part added to the along one (the primary
    alone for a component target)."""
    if station is None:
        return mu_p, mu_s
    if mu_s is None or sm.primary_is_along:
        return mu_p + station, mu_s
    return mu_p, mu_s + station
