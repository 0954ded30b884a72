"""Read a samples table (CSV, Parquet or the daemon's MCAP) into a validated `Survey` in a local metric frame."""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame, wrap_from_minus180
from forcemap.host.workbench.cleaning import check_positions, to_numeric
from forcemap.host.workbench.errors import WorkbenchError

MIN_ROWS = 30
MAX_MISSING_FRACTION = 0.05
# rows with no time or position (a GPS outage, the autopilot stream lost) cannot be placed on the map
# and are dropped; a table where most rows are like that is more likely a broken export
MAX_UNPLACED_FRACTION = 0.5
REQUIRED = ("t", "lat", "lon")
# columns that are bookkeeping, never covariates
NOT_COVARIATES = {"t", "lat", "lon", "x", "y"}
# boat kinematics that respond to the current and wind pushing the boat (yaw_rate is not here: in a survey the
# turns are commanded by the mission, see docs/WORKBENCH.md)
KINEMATIC = ("sog", "cog", "throttle", "crab")


def is_circular(name: str) -> bool:
    """Angles (degrees) that wrap at 360: heading, cog, app_wind_angle, *_dir and derived relative headings."""
    return (
        name in {"heading", "cog", "app_wind_angle", "crab"}
        or name.endswith("_dir")
        or "_rel_" in name
    )


def family(name: str) -> str | None:
    """The column family of CONVENTIONS.md: wind, current, depth, or None."""
    if name.startswith("wind_") or name.startswith("app_wind_"):
        return "wind"
    # the speed through water is the boat's velocity minus the measured current: it carries the current's noise
    if name.startswith("current_") or re.fullmatch(r"wheel\d+_speed", name) or name == "stw":
        return "current"
    if name == "depth":
        return "depth"
    return None


@dataclass
class VectorTarget:
    """A target that is one aspect (speed, dir or a component) of a 2-D vector field."""

    prefix: str  # "wind", "current", "current_paper"
    aspect: str  # "speed", "dir", "east", "north"

    @property
    def name(self) -> str:
        return self.column(self.aspect)

    def column(self, aspect: str) -> str:
        """The table column of one aspect of this vector: wind_east, current_dir_paper, ..."""
        if self.prefix == "current_paper":
            return f"current_{aspect}_paper"
        return f"{self.prefix}_{aspect}"

    def direction(self, east: np.ndarray, north: np.ndarray) -> np.ndarray:
        """Compass direction (deg) of the vector's components, in its convention (wind FROM, current TO)."""
        d = np.degrees(np.arctan2(east, north)) % 360.0
        return (d + 180.0) % 360.0 if self.is_from else d

    @property
    def is_from(self) -> bool:
        """Wind directions say where the air comes FROM; currents where the water goes TO."""
        return self.prefix == "wind"

    @property
    def family(self) -> str:
        return "wind" if self.prefix == "wind" else "current"


@dataclass
class Survey:
    """A samples table in SI units with positions in metres east/north of the survey's centre."""

    columns: dict[str, np.ndarray]
    lat0: float
    lon0: float
    t0: float
    source: Path
    notes: list[str] = field(default_factory=list)
    non_numeric: set[str] = field(default_factory=set)
    cache: dict = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return len(self.columns["t"])

    @property
    def xy(self) -> np.ndarray:
        return np.column_stack([self.columns["x"], self.columns["y"]])

    @property
    def trel(self) -> np.ndarray:
        return self.columns["t"] - self.t0

    def numeric_columns(self) -> list[str]:
        return [c for c in self.columns if c not in NOT_COVARIATES]

    def subset(self, mask: np.ndarray) -> Survey:
        cols = {k: v[mask] for k, v in self.columns.items()}
        return Survey(
            cols,
            self.lat0,
            self.lon0,
            self.t0,
            self.source,
            list(self.notes),
            set(self.non_numeric),
        )

    def column(self, name: str) -> np.ndarray:
        """A numeric column, or a clear error saying why it cannot be used."""
        if name == "t":
            return self.trel
        if name in self.non_numeric:
            raise WorkbenchError(
                f"column '{name}' is not numeric; only numeric columns can be modelled"
            )
        if name not in self.columns:
            raise WorkbenchError(
                f"unknown column '{name}'; numeric columns are: {', '.join(sorted(self.numeric_columns()))}"
            )
        return self.columns[name]

    def vector_target(self, name: str) -> VectorTarget | None:
        """If `name` is the speed, direction or a component of wind or current, the vector it belongs to."""
        m = re.fullmatch(r"(wind|current)_(speed|dir|east|north)(_paper)?", name)
        if not m:
            return None
        prefix = m.group(1) + ("_paper" if m.group(3) else "")
        vt = VectorTarget(prefix, m.group(2))
        e, nn = self.components(vt)
        return vt if e is not None and nn is not None else None

    def components(self, vt: VectorTarget) -> tuple[np.ndarray | None, np.ndarray | None]:
        """East and north components (m/s) of a vector, from the table's components or its speed and dir."""
        e, nn = self.columns.get(vt.column("east")), self.columns.get(vt.column("north"))
        if e is not None and nn is not None:
            return e, nn
        s, d = self.columns.get(vt.column("speed")), self.columns.get(vt.column("dir"))
        if s is None or d is None:
            return None, None
        sign = -1.0 if vt.is_from else 1.0
        rad = np.radians(d)
        return sign * s * np.sin(rad), sign * s * np.cos(rad)


def _read_csv(path: Path) -> dict[str, list[str]]:
    try:
        # utf-8-sig: a byte-order mark (spreadsheets write one) is read, not taken for part of `t`
        with path.open(newline="", encoding="utf-8-sig") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None:
                raise WorkbenchError(f"{path}: the file is empty")
            header = [h.strip() for h in header]
            rows = list(reader)
    except UnicodeDecodeError:
        raise WorkbenchError(
            f"{path}: not UTF-8 text; is it a CSV? (save it from the spreadsheet as CSV UTF-8)"
        ) from None
    except csv.Error as exc:
        raise WorkbenchError(f"{path}: not a readable CSV ({exc})") from None
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise WorkbenchError(
            f"{path}: column name(s) {', '.join(repr(d) for d in dup)} appear more than once in the header"
        )
    cols: dict[str, list[str]] = {h: [] for h in header}
    for i, row in enumerate(rows):
        if len(row) != len(header):
            if not any(cell.strip() for cell in row):
                continue
            raise WorkbenchError(
                f"{path}: row {i + 2} has {len(row)} cells, the header has {len(header)}"
            )
        for h, cell in zip(header, row, strict=True):
            cols[h].append(cell)
    return cols


def _read_parquet(path: Path) -> dict[str, list]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises many types for a bad file
        raise WorkbenchError(f"{path}: not a readable Parquet file ({exc})") from None
    out: dict[str, list] = {}
    for name in table.column_names:
        col = table.column(name)
        # numeric columns as arrays (nulls as NaN): `to_numeric` takes them whole, not cell by cell
        if pa.types.is_floating(col.type) or pa.types.is_integer(col.type):
            out[name] = col.to_numpy(zero_copy_only=False).astype(float)  # type: ignore[assignment]
        else:
            out[name] = col.to_pylist()
    return out


def _read_mcap(path: Path) -> dict[str, list]:
    """The ``/samples`` rows through `forcemap export`'s reader: truncated logs are read up to their
    last complete chunk, and rows repeated (same ``t``) are kept once."""
    from forcemap.host.convert.export import check_logs, samples_table
    from forcemap.host.errors import CliError

    try:
        check_logs([path])
    except CliError as exc:
        raise WorkbenchError(str(exc)) from None
    table = samples_table([path])
    if not len(table):
        raise WorkbenchError(
            f"{path}: the MCAP log has no /samples messages; was it written by `forcemap run`?"
        )
    return {c: table.column(c) for c in table.columns}


def read_raw(path: str | Path) -> dict[str, list]:
    """The table's cells by column, from CSV, Parquet or MCAP (chosen by the file's extension)."""
    path = Path(path)
    if not path.exists():
        raise WorkbenchError(f"{path}: no such file")
    if path.is_dir():
        raise WorkbenchError(f"{path} is a folder; give a samples table (.csv, .parquet or .mcap)")
    suffix = path.suffix.lower()
    if suffix == ".parquet" or suffix == ".pq":
        return _read_parquet(path)
    if suffix == ".mcap":
        return _read_mcap(path)
    return _read_csv(path)


def _fill_nearest_in_time(values: np.ndarray) -> np.ndarray:
    good = np.flatnonzero(np.isfinite(values))
    idx = np.arange(len(values))
    pos = (
        np.clip(np.searchsorted(good, idx), 1, len(good) - 1)
        if len(good) > 1
        else np.zeros_like(idx)
    )
    if len(good) == 1:
        return np.full_like(values, values[good[0]])
    left, right = good[pos - 1], good[pos]
    nearest = np.where(np.abs(idx - left) <= np.abs(right - idx), left, right)
    return np.where(np.isfinite(values), values, values[nearest])


def _numeric_columns(path: Path, raw: dict[str, list]) -> tuple[dict, set[str], list[str]]:
    """Numeric columns (cells that are not numbers, and inf, made missing with a note) and the rest."""
    columns: dict[str, np.ndarray] = {}
    non_numeric: set[str] = set()
    notes: list[str] = []
    for name, cells in raw.items():
        col = to_numeric(cells)
        if col is None:
            non_numeric.add(name)
            continue
        columns[name] = col.values
        notes += col.notes(name)
    for c in REQUIRED:
        if c in non_numeric:
            raise WorkbenchError(f"{path}: column '{c}' is not numeric")
    return columns, non_numeric, notes


def _placed_rows(path: Path, columns: dict[str, np.ndarray], notes: list[str]) -> np.ndarray:
    """Data rows (0-based, in time order) that have a time and a position a boat could be at."""
    if len(columns["t"]) == 0:
        raise WorkbenchError(f"{path}: the table has a header but no rows")
    keep = np.ones(len(columns["t"]), bool)
    for c in REQUIRED:
        bad = ~np.isfinite(columns[c])
        if bad.mean() > MAX_UNPLACED_FRACTION:
            raise WorkbenchError(
                f"{path}: column '{c}' has {bad.mean():.0%} missing values; a row needs t, lat, lon to be mapped"
            )
        if bad.any():
            notes.append(
                f"dropped {bad.sum()} row(s) with missing '{c}' (no time or position: GPS or autopilot outage)"
            )
        keep &= ~bad
    rows = np.flatnonzero(keep)
    rows = rows[np.argsort(columns["t"][rows], kind="stable")]
    if len(rows) == 0:
        return rows
    ok, more = check_positions(
        path,
        columns["t"][rows],
        columns["lat"][rows],
        columns["lon"][rows],
        rows,
        MAX_UNPLACED_FRACTION,
    )
    notes += more
    return rows[ok]


def load_survey(path: str | Path) -> Survey:
    """Read and validate a samples table; positions become metres east/north of the survey centre."""
    path = Path(path)
    raw = read_raw(path)
    missing = [c for c in REQUIRED if c not in raw]
    if missing:
        raise WorkbenchError(
            f"{path}: required column(s) missing: {', '.join(missing)} (need t, lat, lon)"
        )
    columns, non_numeric, notes = _numeric_columns(path, raw)
    return survey_from_columns(path, columns, non_numeric, notes)


def survey_from_columns(
    path: Path,
    columns: dict[str, np.ndarray],
    non_numeric: set[str] | None = None,
    notes: list[str] | None = None,
) -> Survey:
    """A `Survey` from numeric columns (with t, lat, lon) already in memory, checked as `load_survey` does:
    the live map builds its surveys this way from the samples so far."""
    non_numeric, notes = set(non_numeric or ()), list(notes or [])
    rows = _placed_rows(path, columns, notes)
    columns = {k: v[rows] for k, v in columns.items()}
    n = len(rows)
    if n < MIN_ROWS:
        raise WorkbenchError(
            f"{path}: only {n} usable rows; the workbench needs at least {MIN_ROWS}"
        )
    lat, lon = columns["lat"], columns["lon"]
    lat0 = 0.5 * (float(lat.min()) + float(lat.max()))
    lon0 = 0.5 * (float(lon.min()) + float(lon.max()))
    columns["x"], columns["y"] = LocalFrame(lat0, lon0).to_local(lat, lon)
    if "heading" in columns and "cog" in columns:
        columns["crab"] = wrap_from_minus180(columns["heading"] - columns["cog"])
    survey = Survey(columns, lat0, lon0, float(columns["t"][0]), path, notes, non_numeric)
    return survey


def prepare_column(
    survey: Survey, name: str, role: str, allow_constant: bool = False
) -> np.ndarray:
    """A column ready for modelling: numeric, not constant, few enough gaps (filled nearest in time, with a note)."""
    values = survey.column(name)
    bad = ~np.isfinite(values)
    if bad.all():
        raise WorkbenchError(
            f"{role} '{name}' has no values (every cell is empty, not a number or inf)"
        )
    if bad.mean() > MAX_MISSING_FRACTION:
        raise WorkbenchError(
            f"{role} '{name}' has {bad.mean():.0%} missing values (at most {MAX_MISSING_FRACTION:.0%} can be filled)"
        )
    if bad.any():
        values = _fill_nearest_in_time(values)
        note = f"filled {bad.sum()} missing value(s) of '{name}' with the nearest sample in time"
        if note not in survey.notes:
            survey.notes.append(note)
    finite = values[np.isfinite(values)]
    if allow_constant:
        return values
    if np.ptp(finite) <= 1e-12 * max(1.0, float(np.abs(finite).max())):
        raise WorkbenchError(
            f"{role} '{name}' is constant ({finite[0]:g}); there is nothing to model"
        )
    return values
