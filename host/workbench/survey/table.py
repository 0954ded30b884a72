"""Read a samples table (CSV, Parquet or the daemon's MCAP) into a validated `Survey` in a local metric frame."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame, wrap_from_minus180
from forcemap.host.vessel.reference_current import ReferenceCurrent
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.cleaning import check_positions
from forcemap.host.workbench.survey.table_files import (  # noqa: F401 - part of this API
    mcap_latencies,
    mcap_provenance,
    read_numeric,
    read_raw,
)

MIN_ROWS = 30
# rows with no time or position (a GPS outage, the autopilot stream lost) cannot be placed on the map
# and are dropped; a table where most rows are like that is more likely a broken export
MAX_UNPLACED_FRACTION = 0.5
REQUIRED = ("t", "lat", "lon")
# columns that are bookkeeping, never covariates
# an ADCP's flags, the rows an import found the bottom lost in, and each sounding's uncertainty
NOT_COVARIATES = {
    "t", "lat", "lon", "x", "y", "position_dr", "boat_vel_filled", "bottom_lost", "depth_tvu",
}  # fmt: skip
# flag columns (spike_depth, spike_current, ...): bookkeeping too
FLAG_PREFIX = "spike_"
# boat kinematics that respond to the current and wind pushing the boat (yaw_rate is not here: in a survey the
# turns are commanded by the mission, see docs/WORKBENCH.md)
KINEMATIC = ("sog", "cog", "throttle", "crab", "boat_east", "boat_north")  # boat_*: an ADCP's


def is_circular(name: str) -> bool:
    """Angles (degrees) that wrap at 360: heading, cog, app_wind_angle, *_dir and derived relative headings."""
    return (
        name in {"heading", "cog", "app_wind_angle", "crab"}
        or name.endswith("_dir")
        or name.endswith("_dir_davg")
        or "_rel_" in name
    )


def unit_of(name: str) -> str:
    """The unit of a column or model input as printed (docs/CONVENTIONS.md): "m/s", "m", "deg", ... ("" if
    it has none that forcemap knows)."""
    if is_circular(name):
        return "deg"
    if name in ("position", "x", "y", "depth", "depth_raw", "depth_tvu") or name.endswith("_m"):
        return "m"
    if name in ("roll", "pitch"):  # the hull's attitude (or an ADCP's tilts)
        return "deg"
    if name == "t":
        return "s"
    if name == "yaw_rate":
        return "deg/s"
    if name == "water_temp":
        return "degC"
    if name in ("sog", "stw") or re.search(r"_(speed|east|north)(_\w+)?$", name):
        return "m/s"
    return ""


# what a log needs for a family's vectors beyond a fix: a heading turns the water's or the air's
# velocity past the boat into the earth's frame, a speed through the water gives the water's
NEEDS = {
    "current": (("heading", "the boat's heading (a compass)"), ("stw", "its speed through the water")),
    "wind": (("heading", "the boat's heading (a compass)"),),
}


def why_absent(columns, name: str) -> str:
    """Why the table (its ``columns``) has no ``name`` of the wind or current family: what the log
    lacked; '' when it lacked none of that, or ``name`` is not of those families."""
    fam = family(name)
    lacking = [words for column, words in NEEDS.get(fam or "", ()) if column not in columns]
    if not lacking:
        return ""
    return f"a {fam} needs {' and '.join(lacking)}, which this log lacks"


def family(name: str) -> str | None:
    """The column family of CONVENTIONS.md: wind, current, depth, or None."""
    if name.startswith("wind_") or name.startswith("app_wind_"):
        return "wind"
    # the speed through water is the boat's velocity minus the measured current: it carries the current's noise
    if name.startswith("current_") or re.fullmatch(r"wheel\d+_speed", name) or name == "stw":
        return "current"
    # the sounding as read before its tilt correction is the target's own raw reading
    if name in ("depth", "depth_raw"):
        return "depth"
    return None


@dataclass
class VectorTarget:
    """A target that is one aspect (speed, dir or a component) of a 2-D vector field."""

    prefix: str  # "wind", "current", "current_paper", "current_davg" (an ADCP's depth average)
    aspect: str  # "speed", "dir", "east", "north"

    @property
    def name(self) -> str:
        return self.column(self.aspect)

    def column(self, aspect: str) -> str:
        """The table column of one aspect of this vector: wind_east, current_dir_paper, ..."""
        if self.prefix in ("current_paper", "current_davg"):
            return f"current_{aspect}_{self.prefix[len('current_') :]}"
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
    # --keep-outliers: spikes are flagged but stay in the fits (host/workbench/survey/spikes.py)
    keep_outliers: bool = False
    # the targets (a vector by its prefix) whose spikes this survey has already left out
    spikes_removed: set[str] = field(default_factory=set)
    # who fed each column (the MCAP's `columns` metadata; empty for a CSV): host/workbench/sources.py
    provenance: dict[str, str] = field(default_factory=dict)
    # what the depth column is measured from once reduced to a gauge (host/workbench/depth/water_level.py)
    datum: str | None = None
    # each navigation source's measured latency (host/convert/navigation_table.latencies; MCAP only)
    latencies: dict[str, dict] = field(default_factory=dict)
    # the reference current its tide is related to (`--reference-current`; host/workbench/survey/reference.py)
    reference: ReferenceCurrent | None = None
    # a subset's survey of origin (None: this is one) and its rows there: a covariate's gaps are measured,
    # and bridged, on every reading the origin has (host/workbench/survey/gaps.py)
    root: Survey | None = field(default=None, repr=False)
    index: np.ndarray | None = field(default=None, repr=False)

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
        return [
            c for c in self.columns if c not in NOT_COVARIATES and not c.startswith(FLAG_PREFIX)
        ]

    @property
    def origin(self) -> tuple[Survey, np.ndarray]:
        """The survey this one's rows were taken from, and their rows there."""
        if self.root is None:
            return self, np.arange(self.n)
        return self.root, self.index  # type: ignore[return-value]

    def subset(self, mask: np.ndarray) -> Survey:
        cols = {k: v[mask] for k, v in self.columns.items()}
        root, index = self.origin
        return Survey(
            cols,
            self.lat0,
            self.lon0,
            self.t0,
            self.source,
            list(self.notes),
            set(self.non_numeric),
            keep_outliers=self.keep_outliers,
            spikes_removed=set(self.spikes_removed),
            provenance=dict(self.provenance),
            datum=self.datum,
            latencies=dict(self.latencies),
            reference=self.reference,
            root=root,
            index=index[mask],
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
        m = re.fullmatch(r"(wind|current)_(speed|dir|east|north)(_paper|_davg)?", name)
        if not m:
            return None
        prefix = m.group(1) + (m.group(3) or "")
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


def _numeric_columns(path: Path) -> tuple[dict, set[str], list[str]]:
    """Numeric columns (cells that are not numbers, and inf, made missing with a note), the other columns'
    names, and notes on the reading (a truncated log's first)."""
    numeric, non_numeric, notes = read_numeric(path)
    columns: dict[str, np.ndarray] = {}
    for name, col in numeric.items():
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
                f"dropped {bad.sum()} row(s) with missing '{c}' (no time or position: a GNSS or navigation-stream outage)"
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


def load_survey(path: str | Path, keep_outliers: bool = False) -> Survey:
    """Read and validate a samples table; positions become metres east/north of the survey centre.
    With `keep_outliers`, spikes are flagged but stay in the fits (host/workbench/survey/spikes.py)."""
    path = Path(path)
    columns, non_numeric, notes = _numeric_columns(path)
    missing = [c for c in REQUIRED if c not in columns and c not in non_numeric]
    if missing:
        raise WorkbenchError(
            f"{path}: required column(s) missing: {', '.join(missing)} (need t, lat, lon)"
        )
    survey = survey_from_columns(path, columns, non_numeric, notes)
    survey.keep_outliers = keep_outliers
    if path.suffix.lower() == ".mcap":
        survey.provenance = mcap_provenance(path)
        survey.latencies = mcap_latencies(path)
    return survey


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
    return Survey(columns, lat0, lon0, float(columns["t"][0]), path, notes, non_numeric)
