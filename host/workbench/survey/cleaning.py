"""Turn a table's cells into clean numeric columns, and drop the rows no boat could have been at.

Nothing is dropped silently: every cell made missing and every row dropped is counted in a note that
names it, and a table where most rows are unusable is an error, not a map.

- A cell that is not a number (``1,5``, ``n/a``) becomes missing; its column is kept as long as most
  of its cells are numbers (a column of words is not numeric at all).
- inf is missing.
- lat outside -90..90, lon outside -180..180: the row is dropped.
- A position that jumps faster than any survey boat moves (``MAX_BOAT_SPEED`` from the track around
  it: a GPS glitch, lat and lon swapped in some rows) is dropped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.errors import WorkbenchError

# a small ASV surveys at 1-3 m/s; 20 m/s (39 kn) is beyond any of them, even downwind on a river in flood
MAX_BOAT_SPEED = 20.0
# GPS scatter between two fixes that are close in time
GPS_SLACK_M = 50.0
_EMPTY = ("", "nan", "NaN", "NAN", "null", "None", "NA", "N/A", "n/a")
_SHOW = 3  # examples named in a note


@dataclass
class NumericColumn:
    """A column's numbers (NaN where missing) and what was made missing, by data row (0-based)."""

    values: np.ndarray
    not_numbers: list[tuple[int, str]]
    infinite: list[int]

    def notes(self, name: str) -> list[str]:
        out = []
        if self.not_numbers:
            n = len(self.not_numbers)
            shown = ", ".join(f"{i + 1} {text!r}" for i, text in self.not_numbers[:_SHOW])
            more = ", ..." if n > _SHOW else ""
            hint = (
                "; a decimal comma? write 1.5, not 1,5"
                if any("," in t for _, t in self.not_numbers)
                else ""
            )
            out.append(
                f"column '{name}': {n} cell(s) that are not numbers made missing "
                f"(data row {shown}{more}){hint}"
            )
        if self.infinite:
            n = len(self.infinite)
            shown = ", ".join(str(i + 1) for i in self.infinite[:_SHOW])
            out.append(
                f"column '{name}': {n} infinite value(s) made missing (data row {shown}"
                f"{', ...' if n > _SHOW else ''})"
            )
        return out


def _number(cell: object) -> float | None:
    """The cell as a float (NaN when empty), or None when it is not a number."""
    if cell is None:
        return math.nan
    if isinstance(cell, bool | int | float):
        return float(cell)
    if isinstance(cell, str):
        text = cell.strip()
        if text in _EMPTY:
            return math.nan
        try:
            return float(text)
        except ValueError:
            return None
    return None


def to_numeric(cells: list, words: bool = False) -> NumericColumn | None:
    """Numbers with NaN for empty, non-numeric and infinite cells; None for a column of words (unless `words`:
    a chunk of a column, judged whole by its reader)."""
    if isinstance(cells, np.ndarray) and cells.dtype.kind == "f":
        values = cells.astype(float)
        inf = np.isinf(values)
        values[inf] = math.nan
        return NumericColumn(values, [], np.flatnonzero(inf).tolist())
    values = np.empty(len(cells))
    not_numbers: list[tuple[int, str]] = []
    infinite: list[int] = []
    for i, cell in enumerate(cells):
        x = _number(cell)
        if x is None:
            not_numbers.append((i, str(cell)[:20]))
            x = math.nan
        elif math.isinf(x):
            infinite.append(i)
            x = math.nan
        values[i] = x
    numbers = int(np.count_nonzero(np.isfinite(values))) + len(infinite)
    if not_numbers and len(not_numbers) >= numbers and not words:
        return None
    return NumericColumn(values, not_numbers, infinite)


def _rows(idx: np.ndarray) -> str:
    shown = ", ".join(str(int(i) + 1) for i in idx[:_SHOW])
    return f"data row {shown}{', ...' if len(idx) > _SHOW else ''}"


def off_globe(lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, str]:
    """Rows whose lat or lon cannot be a place on Earth, and what was wrong with them."""
    bad_lat, bad_lon = np.abs(lat) > 90.0, np.abs(lon) > 180.0
    what = []
    if bad_lat.any():
        what.append(f"lat outside -90..90 (e.g. {lat[bad_lat][0]:g})")
    if bad_lon.any():
        what.append(f"lon outside -180..180 (e.g. {lon[bad_lon][0]:g})")
    return bad_lat | bad_lon, " and ".join(what)


def impossible_jumps(t: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """Rows (in time order) that a boat at MAX_BOAT_SPEED could not reach from the track around them.

    The track is followed forwards and backwards from the fix nearest the median position, so one
    glitch (even the first fix) cannot drag the rest of the track away with it.
    """
    x, y = LocalFrame(float(np.median(lat)), float(np.median(lon))).to_local(lat, lon)
    bad = np.zeros(len(t), bool)
    if len(t) == 0:
        return bad
    anchor = int(np.argmin(np.hypot(x, y)))
    for step in (1, -1):
        last = anchor
        i = anchor + step
        while 0 <= i < len(t):
            reach = MAX_BOAT_SPEED * abs(t[i] - t[last]) + GPS_SLACK_M
            if math.hypot(x[i] - x[last], y[i] - y[last]) > reach:
                bad[i] = True
            else:
                last = i
            i += step
    return bad


def check_positions(
    path: object,
    t: np.ndarray,
    lat: np.ndarray,
    lon: np.ndarray,
    rows: np.ndarray,
    max_fraction: float,
) -> tuple[np.ndarray, list[str]]:
    """Rows (time-ordered arrays) to keep, and a note for each kind dropped; an error when most go."""
    notes = []
    outside, what = off_globe(lat, lon)
    if outside.mean() > max_fraction:
        raise WorkbenchError(
            f"{path}: {outside.sum()} of {len(lat)} rows have {what}; are lat and lon swapped, "
            "or not in degrees?"
        )
    if outside.any():
        notes.append(f"dropped {outside.sum()} row(s) with {what} ({_rows(rows[outside])})")
    keep = ~outside
    if keep.any() and lon[keep].min() < -170.0 and lon[keep].max() > 170.0:
        # lon - lon0 is not wrapped: across 180 the track would fall apart into two halves 40,000 km apart
        raise WorkbenchError(
            f"{path}: the track crosses the antimeridian (longitudes near both +180 and -180); "
            "forcemap's local frame does not wrap longitude, so it cannot map this survey"
        )
    jumps = np.zeros_like(keep)
    jumps[keep] = impossible_jumps(t[keep], lat[keep], lon[keep])
    if jumps.sum() > max_fraction * len(t):
        raise WorkbenchError(
            f"{path}: the position jumps faster than {MAX_BOAT_SPEED:g} m/s in {jumps.sum()} of "
            f"{len(t)} rows; are lat and lon swapped in part of the table, or t not in seconds?"
        )
    if jumps.any():
        notes.append(
            f"dropped {jumps.sum()} row(s) whose position jumps faster than {MAX_BOAT_SPEED:g} m/s "
            f"from the track around them: a GPS glitch, or lat/lon swapped ({_rows(rows[jumps])})"
        )
    return keep & ~jumps, notes
