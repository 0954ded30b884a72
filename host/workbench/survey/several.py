"""Several samples tables as one survey: days of the same water fitted together (`fit a.csv b.csv`,
`forcemap.read_survey([day1, day2])`).

Each table is read and checked alone (`load_survey`), then their rows are put in time order in one
local frame centred on all of them; a column one table lacks is missing (NaN) on its rows, as a gap is.
The record's span runs from the first table's first row to the last's last, gaps and all: a harmonic
tide picks its constituents by the Rayleigh criterion over that span. The survey's workspace is the
first table's (`TABLE.forcemap/`); a fit saved there is rebuilt only on the same rows.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import Survey, load_survey, survey_from_columns

DERIVED = ("x", "y", "crab")  # remade in the common frame


def combine(surveys: list[Survey]) -> Survey:
    """One survey of several, in one frame; notes say which table each came from."""
    if len(surveys) == 1:
        return surveys[0]
    names = list(dict.fromkeys(c for s in surveys for c in s.columns if c not in DERIVED))
    columns = {
        c: np.concatenate([s.columns.get(c, np.full(s.n, np.nan)) for s in surveys]) for c in names
    }
    notes = [f"{s.source.name}: {n}" for s in surveys for n in s.notes]
    span_h = (max(s.columns["t"].max() for s in surveys) - min(s.columns["t"][0] for s in surveys)) / 3600
    notes.append(
        f"{len(surveys)} tables as one survey ({', '.join(s.source.name for s in surveys)}): "
        f"{sum(s.n for s in surveys):,} rows over {span_h:.1f} h, gaps and all"
    )
    non_numeric = set().union(*(s.non_numeric for s in surveys)) - set(names)
    out = survey_from_columns(surveys[0].source, columns, non_numeric, notes)
    first = surveys[0]
    out.keep_outliers = first.keep_outliers
    out.provenance = {k: v for s in reversed(surveys) for k, v in s.provenance.items()}
    out.latencies = dict(first.latencies)
    out.reference = first.reference
    return out


def load_surveys(paths: list[str | Path] | str | Path, keep_outliers: bool = False) -> Survey:
    """One table, or several as one survey (`combine`)."""
    if isinstance(paths, str | Path):
        return load_survey(paths, keep_outliers=keep_outliers)
    paths = [Path(p) for p in paths]
    if not paths:
        raise WorkbenchError("no samples table given")
    if len(set(paths)) < len(paths):
        raise WorkbenchError("a table is given twice; give each day once")
    return combine([load_survey(p, keep_outliers=keep_outliers) for p in paths])
