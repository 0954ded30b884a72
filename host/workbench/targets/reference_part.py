"""A current on a reference: the station's part, the place's relation to it, then the map of what is left.

A tide on a reference current (`terms/reference_tide.py`) relates each place to its station, and the
station's prediction is the relation's natural start: ratio 1, no offset, the flood along the station's
axis. So a vector whose terms put it along its stations' flood axes is taken apart in three, each fitted
on what the one before leaves:

1. the station's prediction r(t), on the component along its flood axis (a scalar east or north
   component: r times the axis's east or north);
2. the relation: the along component's departure from it, fitted by the relation's terms alone (the
   weights are departures from the station, with zero-mean priors: what a day cannot tell stays the
   station's), and a steady flow with them where the tide turns in the record (both the flood and the
   ebb hold a quarter of the rows, `reference_tide.supports_split`): only there can a river's own flow
   be told from a ratio;
3. the model's other terms (the baseline's map, any effect) on what the relation leaves: the map of
   what is left, the across component's too.

Fitted together, a day of one flood cannot tell a mean flow from a ratio, and the marginal likelihood
trades one for the other (a map of +0.4 m/s and a ratio of 0.5 fit the 2014-05-17 log as well as a
ratio of 0.9); the mean flow then predicts the next day's ebb as a flood. In this order the relation
explains what it can. The across component carries no relation: a yacht's leeway sits there, and the
turn it would learn does not carry to another day (bench/RESULTS.md, "A reference current"). The parts
are added back wherever the components are combined into the vector.
"""

from __future__ import annotations

import numpy as np
from forcemap.host.workbench.survey import reference
from forcemap.host.workbench.targets.flow_axis import along_reference
from forcemap.host.workbench.targets.survey_fits import survey_fits, terms_with_basis
from forcemap.host.workbench.terms import registry
from forcemap.host.workbench.terms.reference_tide import supports_split
from forcemap.host.workbench.terms.spec import BASELINE, parse_terms


def applies(sm) -> bool:
    """Whether the `SurveyModel`'s target is modelled as its departure from its stations."""
    return (
        sm.vector is not None
        and sm.survey.reference is not None
        and along_reference(sm.time_terms)
    )


def _relation_specs(sm) -> list:
    return [s for s in sm.term_specs if registry.caps(s).along_reference]


def model_terms(sm) -> list:
    """The terms of the model of what the relation leaves (all of them without a reference)."""
    if getattr(sm, "station_rows", None) is None:
        return sm.term_specs
    from forcemap.host.workbench.survey.table import is_circular

    rest = [s for s in sm.term_specs if not registry.caps(s).along_reference]
    return rest or parse_terms(BASELINE, is_circular)


def secondary_terms(sm) -> tuple[str, ...]:
    """The time terms of the vector's other component: none of a relation to a reference (see above)."""
    if getattr(sm, "station_rows", None) is None:
        return sm.time_terms
    return tuple(t for t in sm.time_terms if not along_reference((t,)))


def rows(sm) -> np.ndarray:
    """The station's prediction on the model's along component (speed, direction) or on its own
    component (east, north) at the survey's rows."""
    return _project(sm, sm.survey.xy, reference.survey_rows(sm.survey)[:, 0])


def _project(sm, xy: np.ndarray, r: np.ndarray) -> np.ndarray:
    aspect = sm.vector.aspect
    if aspect in ("speed", "dir"):
        return r
    ue, un = reference.flood_axes(sm.survey, xy)
    return r * (ue if aspect == "east" else un)


def _along_is_primary(sm) -> bool:
    return sm.vector.aspect != "dir"


def fit_relation(sm) -> None:
    """Fit the relation on the along component's departure from the station (`sm.relation`) and leave
    what it does not explain to the model of the rest (`sm.y_primary` or `sm.y_secondary`)."""
    sm.relation = None
    if sm.station_rows is None:
        return
    specs = _relation_specs(sm)
    if supports_split(reference.survey_rows(sm.survey)[:, 0]):
        # the tide turns in the record: a steady flow (a river's) is told from the ratio, and fitted here
        from forcemap.host.workbench.survey.table import is_circular

        specs = parse_terms(["const"], is_circular) + specs
    built = terms_with_basis(specs)
    along = "y_primary" if _along_is_primary(sm) else "y_secondary"
    y = getattr(sm, along)
    sm.relation = survey_fits(sm.survey).model(built, max_basis=sm.max_basis).fit(sm.X, y)
    sm.relation_rows = sm.relation.predict(sm.X)
    setattr(sm, along, y - sm.relation_rows)


def part(sm, xy: np.ndarray, X: dict) -> np.ndarray | None:
    """The station's prediction and the relation on the along component at places `xy` and the map's
    inputs `X` (their times and reference); None where the target has no reference."""
    if getattr(sm, "relation", None) is None:
        return None
    return _project(sm, xy, X[reference.INPUT][:, 0]) + sm.relation.predict(X)


def cv_part(sm, folds: np.ndarray) -> np.ndarray | None:
    """`part` at the survey's rows with the relation held out as the model is (refitted per fold)."""
    if getattr(sm, "relation", None) is None:
        return None
    return sm.station_rows + sm.relation.cv_predict(folds, return_std=False)[0]


def add_along(sm, mu_p: np.ndarray, mu_s, station: np.ndarray | None):
    """The primary and secondary means with the station's part added to the along one (the primary
    alone for a component target)."""
    if station is None:
        return mu_p, mu_s
    if mu_s is None or sm.primary_is_along:
        return mu_p + station, mu_s
    return mu_p, mu_s + station
