"""The work done per log, on whichever worker gets it: read the log (MCAP or samples table), place it in the
season's common frame, and reduce it to sufficient statistics. A log that cannot be used comes back as a
`Rejected` with one line saying why; it never stops the season. Every function here is a plain, picklable
top-level function of small arguments: the same code runs in one process or on a Dask worker."""

from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.season.stats import (
    ConstAndGP,
    Prior,
    Stats,
    chunk_stats,
    fit_hypers,
    masked_stats,
    posterior,
    target_scale,
    without_offset,
)
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.depth.water_level import reduce_to_gauge
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.gaps import target_gaps
from forcemap.host.workbench.survey.table import Survey, load_survey
from forcemap.host.workbench.survey.target_rows import target_rows
from forcemap.host.workbench.targets.survey_fits import HYPER_SPACING_S, MIN_HYPER_ROWS
from forcemap.host.workbench.validation.cv import blocked_folds

# the statistics' targets and their columns: depth and the current share the spatial basis, each on the
# rows that have it
TARGETS = {"depth": ("depth",), "current": ("current_east", "current_north"),
           "wind": ("wind_east", "wind_north")}  # fmt: skip
# glibc's mallopt parameters
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD, M_ARENA_MAX = -1, -3, -8


@dataclass
class Rejected:
    """A log left out of the season, and why (one line)."""

    path: str
    reason: str


@dataclass
class Footprint:
    """Where and when a log was taken: enough to choose the season's frame and basis."""

    path: str
    lat: tuple[float, float]
    lon: tuple[float, float]
    t: tuple[float, float]
    n: int


@dataclass
class Frame:
    """The season's common local frame and the fixed bases of its maps (`HilbertGPTerm`s, set up once)."""

    lat0: float
    lon0: float
    space: object
    wind: object
    extent: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # x0, x1, y0, y1 of the tracks
    # a water-level gauge's record (`workbench.water_level.Gauge`): every log's depth reduced to its datum
    gauge: object = None

    def xy(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        return np.column_stack(LocalFrame(self.lat0, self.lon0).to_local(lat, lon))

    @property
    def space_features(self) -> ConstAndGP:
        """The depth and current maps' features: `space_features(Z)` (n x m)."""
        return ConstAndGP(self.space)

    @property
    def wind_features(self) -> ConstAndGP:
        """The wind maps' features (the coarse basis)."""
        return ConstAndGP(self.wind)


class Bundle(dict):
    """Named `Stats`, summed name by name (the unit of the tree reduction)."""

    def __add__(self, other: Bundle) -> Bundle:
        return Bundle({k: self[k] + other[k] for k in self})


@dataclass
class SurveyResult:
    """One log's statistics, each target's on the rows that have it (`workbench.gaps.target_gaps`):
    `depth` and `current` (east, north) against the spatial basis, `wind` (east, north) against the wind
    basis; each also over the hyperparameter rows (`depth_hyper`, ...). `has` names the target columns the
    log measured (a missing one has no rows)."""

    path: str
    t0: float
    t1: float
    n: int
    has: dict[str, bool]
    stats: Bundle
    notes: list[str] = field(default_factory=list)
    wind: object = (
        None  # the survey's own wind map (`model.fit_wind`), fitted where the log was read
    )

    @property
    def t_mid(self) -> float:
        return 0.5 * (self.t0 + self.t1)


def _load(path: str) -> Survey:
    try:
        return load_survey(path)
    except WorkbenchError:
        raise
    except (OSError, ValueError, KeyError, IndexError, EOFError) as e:
        # a truncated or corrupt file: the readers' own errors, said in one line
        raise WorkbenchError(f"{path}: cannot be read ({type(e).__name__}: {e})") from None


def _parquet_placement(path: str) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """t, lat, lon of a Parquet table's placed rows, read as three columns (None: let the full reader say)."""
    import pyarrow.parquet as pq

    try:
        cols = pq.read_table(path, columns=["t", "lat", "lon"])
        t, lat, lon = (
            np.asarray(cols[c].to_numpy(zero_copy_only=False), float) for c in ("t", "lat", "lon")
        )
    except Exception:  # noqa: BLE001 - any failure here is reported by the full reader
        return None
    ok = np.isfinite(t) & np.isfinite(lat) & np.isfinite(lon)
    ok &= (np.abs(lat) <= 90) & (np.abs(lon) <= 180) & ((lat != 0) | (lon != 0))
    if ok.mean() < 0.5 or ok.sum() < 30:
        return None
    return t[ok], lat[ok], lon[ok]


def footprint(path: str) -> Footprint | Rejected:
    """A log's extent and time span: three columns of a Parquet table, else the whole log, validated (the
    statistics pass validates every log in full)."""
    placed = _parquet_placement(path) if path.endswith(".parquet") else None
    if placed is not None:
        t, lat, lon = placed
        return Footprint(
            path, (float(lat.min()), float(lat.max())), (float(lon.min()), float(lon.max())),
            (float(t.min()), float(t.max())), len(t),
        )  # fmt: skip
    try:
        s = _load(path)
    except WorkbenchError as e:
        return Rejected(path, str(e))
    lat, lon, t = s.columns["lat"], s.columns["lon"], s.columns["t"]
    return Footprint(
        path,
        (float(lat.min()), float(lat.max())),
        (float(lon.min()), float(lon.max())),
        (float(t.min()), float(t.max())),
        s.n,
    )


def hyper_mask(t: np.ndarray) -> np.ndarray:
    """The rows whose marginal likelihood sets the hyperparameters: the first sample of every
    HYPER_SPACING_S, as a single survey's fit uses (`workbench.survey_fits.SurveyFits.hyper_rows`)."""
    _, rows = np.unique(np.floor((t - t.min()) / HYPER_SPACING_S), return_index=True)
    if len(rows) < MIN_HYPER_ROWS:
        rows = np.unique(np.linspace(0, len(t) - 1, min(MIN_HYPER_ROWS, len(t))).astype(int))
    mask = np.zeros(len(t), bool)
    mask[rows] = True
    return mask


def _targets(s: Survey) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], dict[str, bool], list]:
    """Each target's columns and the rows that have it (none where the log lacks it), which target
    columns it has, and what was left out, in words."""
    out, has, notes = {}, {}, []
    for name, cols in TARGETS.items():
        vt = s.vector_target(cols[0])
        try:
            gaps = target_gaps(s, cols[0]) if vt or len(cols) == 1 else None
        except WorkbenchError:  # the log does not measure it
            gaps = None
        ok = np.zeros(s.n, bool) if gaps is None else ~gaps.missing
        if name == "depth" and ok.any():
            ok, line = _depth_rows(s)
            notes += [line] if line else []
        has.update({c: bool(ok.any()) for c in cols})
        if gaps is not None and ok.any() and gaps.count:
            notes.append(gaps.line(f"the season's {name} uses the other {{used:,}}"))
        Y = np.zeros((s.n, len(cols)))
        if ok.any():
            Y[ok] = np.column_stack(s.components(vt) if vt else [s.columns[cols[0]]])[ok]
        out[name] = (Y, ok)
    return out, has, notes


def _depth_rows(s: Survey) -> tuple[np.ndarray, str]:
    """The rows every depth map of ``s`` is fitted on (`target_rows`: its spikes, the bottom lost and the
    soundings the depth surface rejects left out, unless it keeps outliers), and what was left out."""
    try:
        rows = target_rows(s, "depth")
    except WorkbenchError:  # too few soundings left: none of them
        return np.zeros(s.n, bool), ""
    said = rows.spikes.lines() if rows.spikes is not None and not s.keep_outliers else []
    return rows.used, "the season's depth leaves out " + "; ".join(said) if said else ""


def read_placed(path: str, frame: Frame) -> tuple[Survey, np.ndarray]:
    s = _load(path)
    if frame.gauge is not None:
        s = reduce_to_gauge(s, frame.gauge)
    return s, frame.xy(s.columns["lat"], s.columns["lon"])


@functools.lru_cache(maxsize=1)
def roomy_heap() -> None:
    """Large temporaries from the heap, not fresh pages, in this process from now on (once per process).

    A Dask worker runs with MALLOC_TRIM_THRESHOLD_=65536 (distributed's default, to give memory back),
    which makes glibc map every block over 128 kB afresh: each 8,192 x m feature chunk and its
    temporaries are page-faulted and zeroed again, and the statistics pass ran 25-30 % slower on a
    worker than in one process. The heap keeps up to 256 MB. (It used to be given back after every log:
    the next log then faulted its pages in again, and a worker spent 5-10 % more CPU per log than one
    process; a worker's peak RSS stays ~400 MB either way.) A task runs in a worker's thread, and glibc
    gives a thread its own arena, grown 64 MB at a time and trimmed apart from these settings: one arena for
    all threads (`engine` calls this when a worker starts, before its task threads exist) makes a log cost
    on a worker what it costs in one process. Elsewhere than glibc, nothing happens."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    except (OSError, AttributeError):
        return
    libc.mallopt(M_TRIM_THRESHOLD, 256 << 20)
    libc.mallopt(M_MMAP_THRESHOLD, 64 << 20)
    libc.mallopt(M_ARENA_MAX, 1)


def survey_stats(path: str, frame: Frame) -> SurveyResult | Rejected:
    """A log's sufficient statistics in the season's frame (streamed over row chunks)."""
    roomy_heap()
    return _survey_stats(path, frame)


def _survey_stats(path: str, frame: Frame) -> SurveyResult | Rejected:
    try:
        s, Z = read_placed(path, frame)
    except WorkbenchError as e:
        return Rejected(path, str(e))
    t = s.columns["t"]
    hyper = hyper_mask(t)
    targets, has, left = _targets(s)
    stats, notes = Bundle(), list(s.notes) + left
    for group, feats in ((("depth", "current"), frame.space_features), (("wind",), frame.wind_features)):
        stats.update(masked_stats(feats, Z, {k: targets[k] for k in group}))
        hyp = {k + "_hyper": (targets[k][0][hyper], targets[k][1][hyper]) for k in group}
        stats.update(masked_stats(feats, Z[hyper], hyp))
    if not has["depth"] and not has["current_east"]:
        return Rejected(path, f"{path}: neither depth nor current measured; nothing to map")
    result = SurveyResult(path, float(t.min()), float(t.max()), s.n, has, stats, notes)
    result.wind = fit_wind(frame, result)
    return result


def fit_wind(frame: Frame, r: SurveyResult):
    """One survey's wind map on the coarse wind basis, with its own hyperparameters: (posterior, theta)."""
    if not (r.has["wind_east"] and r.has["wind_north"]):
        return None
    prior = Prior(frame.wind)
    full, hyper = r.stats["wind"], r.stats["wind_hyper"]
    y_scale = float(np.mean(target_scale(full)))
    theta, _ = fit_hypers(prior, hyper, y_scale)
    return posterior(prior, theta, full, y_scale), theta


def depth_cv(path: str, frame: Frame, season, k: int = 5) -> dict | Rejected:
    """Blocked CV of one survey's depth: its own map (its own hyperparameters, fitted on its own statistics)
    against the season's static map, both refitted without the held-out blocks of this survey."""
    try:
        s, Z = read_placed(path, frame)
    except WorkbenchError as e:
        return Rejected(path, str(e))
    y = s.columns.get("depth")
    if y is None or not np.isfinite(y).any():
        return Rejected(path, f"{path}: no depth for the blocked CV")
    ok = _depth_rows(s)[0]  # the rows every depth map is fitted on (`workbench.target_rows`)
    if not ok.any():
        return Rejected(path, f"{path}: too few soundings left for the blocked CV")
    s, Z, y = s.subset(ok), Z[ok], y[ok]
    folds, _ = blocked_folds(s.xy, k)
    feats = frame.space_features
    with_level = season.levels is not None and path in season.paths
    own_all = chunk_stats(feats, Z, y[:, None])
    own_hyper = chunk_stats(
        feats, Z[hyper_mask(s.columns["t"])], y[hyper_mask(s.columns["t"])][:, None]
    )
    scale = float(target_scale(own_all)[0])
    theta_own, _ = fit_hypers(season.prior, own_hyper, scale)
    sq_own = sq_static = 0.0
    for f in np.unique(folds):
        test = folds == f
        held = chunk_stats(feats, Z[test], y[test][:, None])
        Phi = feats(Z[test])
        own = posterior(season.prior, theta_own, _minus(own_all, held), scale)
        train = _minus(own_all, held)
        if with_level:
            # the survey's level profiled out of its training rows, as in the season's fit
            rest = _minus(season.total, without_offset(own_all)) + without_offset(train)
            static = posterior(season.prior, season.theta, rest, season.y_scale)
            W = static.mean[:, 0]
            level = (train.B[0, 0] - train.G[0] @ W) / max(train.n, 1)
        else:
            static = posterior(
                season.prior, season.theta, _minus(season.total, held), season.y_scale
            )
            level = 0.0
        sq_own += float(((y[test] - own.predict(Phi, False)[0][:, 0]) ** 2).sum())
        pred = static.predict(Phi, False)[0][:, 0] + level
        sq_static += float(((y[test] - pred) ** 2).sum())
    return {
        "path": path,
        "rmse_own": (sq_own / len(y)) ** 0.5,
        "rmse_static": (sq_static / len(y)) ** 0.5,
        "n": len(y),
    }


def _minus(a: Stats, b: Stats) -> Stats:
    return Stats(a.G - b.G, a.B - b.B, a.R - b.R, a.n - b.n)
