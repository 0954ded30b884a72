"""Maps on a regular grid in the survey's UTM zone: the cells, their lat/lon, the mask, and the model's values.

The chain from a cell to a value: the cell centre (UTM easting, northing) -> lat/lon (pyproj, WGS 84) -> the
survey's local frame (`vessel.geodesy.LocalFrame`, metres east/north of its centre, where the models were fitted)
-> the model's prediction. Cells farther than `max_distance` from every sample are masked (NaN): a map is
only as good as where the boat went.

The zone is the one holding the survey's centre (with the exceptions for Norway and Svalbard; pyproj's
`query_utm_crs_info` goes by EPSG's bounding boxes, which overlap there, so it is not used). A survey that spans a zone boundary is gridded in its centre's zone, with a note: a transverse
Mercator projection stays conformal and within 1e-3 of scale a few degrees past its zone's edge, far more
than any boat survey. Beyond UTM's limits (north of 84 N, south of 80 S) the survey is refused in one line,
never projected wrongly.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import Survey
from forcemap.host.workbench.targets.survey_fits import held_notes
from scipy.spatial import cKDTree

UTM_NORTH_LIMIT, UTM_SOUTH_LIMIT = 84.0, -80.0
MAX_CELLS = 20_000_000
# at least this far around every sample is mapped, however dense the survey (see `default_max_distance`)
MIN_MAX_DISTANCE_M = 10.0


@dataclass
class Layer:
    """One target's maps on the grid: band name -> (ny, nx) array, NaN in masked cells."""

    target: str
    terms: list[str]
    bands: dict[str, np.ndarray]
    vector: str | None = (
        None  # "current" or "wind" for a vector target, with east/north/speed/dir bands
    )
    prefix: str | None = None  # the vector's column prefix: "current", "wind", "current_paper"
    datum: str | None = None  # what a depth map is measured from (workbench.water_level.map_datum)
    # what the layer left blank beyond the grid's mask, and why (`trusted`)
    notes: list[str] = field(default_factory=list)
    calibration: object = None  # the model's `cv.Calibration`, if it has one


@dataclass
class MapGrid:
    """A north-up grid of cell centres in a UTM zone, with the layers evaluated on it."""

    epsg: int
    x0: float  # west edge (m, easting)
    y1: float  # north edge (m, northing)
    resolution: float
    nx: int
    ny: int
    lat: np.ndarray  # (ny, nx) cell centres
    lon: np.ndarray
    mask: np.ndarray  # (ny, nx) True where mapped
    max_distance: float
    time_span: tuple[float, float]  # unix seconds of the survey's first and last samples
    layers: dict[str, Layer] = field(default_factory=dict)
    at: float | None = None  # unix seconds the maps are evaluated at (None: the survey's mid-time)
    mid_time: float = 0.0  # unix seconds of the survey's median sample
    notes: list[str] = field(default_factory=list)
    local_xy: np.ndarray = field(
        default=None, repr=False
    )  # (ny*nx, 2) cell centres in the survey frame
    distance: np.ndarray = field(
        default=None, repr=False
    )  # (ny, nx) m to the nearest sample (inf: masked)

    @property
    def easting(self) -> np.ndarray:
        return self.x0 + self.resolution * (np.arange(self.nx) + 0.5)

    @property
    def northing(self) -> np.ndarray:
        return self.y1 - self.resolution * (np.arange(self.ny) + 0.5)

    @property
    def time(self) -> float:
        """UNIX seconds the maps are evaluated at: `at`, or the survey's mid-time (its median sample)."""
        return float(self.at if self.at is not None else self.mid_time)

    def time_iso(self) -> str:
        return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(self.time))

    def time_coverage(self) -> tuple[str, str]:
        """The survey's first and last sample times, ISO 8601 UTC."""
        return tuple(time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(t)) for t in self.time_span)

    @property
    def zone_name(self) -> str:
        if self.epsg == 0:
            return "the survey's local frame"
        return f"UTM zone {self.epsg % 100}{'N' if self.epsg < 32700 else 'S'}"


def utm_zone(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """UTM zone numbers of positions (degrees), with the grid's exceptions: south-west Norway is in
    zone 32 (56-64 N, 3-12 E), and Svalbard (72-84 N) in zones 31, 33, 35 and 37 only."""
    lat, lon = np.asarray(lat, float), np.asarray(lon, float)
    zone = np.floor((lon + 180.0) / 6.0).astype(int) % 60 + 1
    zone = np.where((lat >= 56) & (lat < 64) & (lon >= 3) & (lon < 12), 32, zone)
    svalbard = (lat >= 72) & (lat <= 84) & (lon >= 0) & (lon < 42)
    edges, zones = np.array([9.0, 21.0, 33.0]), np.array([31, 33, 35, 37])
    return np.where(svalbard, zones[np.searchsorted(edges, lon, side="right")], zone)


def utm_epsg(lat: np.ndarray, lon: np.ndarray) -> tuple[int, list[str]]:
    """EPSG code of the WGS 84 UTM zone of a survey's centre, and notes; a one-line refusal where UTM
    cannot map it (polar, or a track across the antimeridian, which the local frame cannot hold)."""
    lat_lo, lat_hi = float(np.min(lat)), float(np.max(lat))
    lon_lo, lon_hi = float(np.min(lon)), float(np.max(lon))
    if lat_hi > UTM_NORTH_LIMIT or lat_lo < UTM_SOUTH_LIMIT:
        raise WorkbenchError(
            f"the survey reaches latitude {lat_hi if lat_hi > UTM_NORTH_LIMIT else lat_lo:.4f}, beyond "
            "UTM's limits (80 S to 84 N); forcemap does not grid polar surveys"
        )
    if lon_hi - lon_lo > 180.0:
        raise WorkbenchError(
            f"the survey's longitudes run from {lon_lo:.4f} to {lon_hi:.4f}: it crosses the antimeridian, "
            "which forcemap's local frame does not wrap; it cannot be gridded"
        )
    lat0, lon0 = 0.5 * (lat_lo + lat_hi), 0.5 * (lon_lo + lon_hi)
    zone = int(utm_zone(lat0, lon0))
    hemi = "N" if lat0 >= 0.0 else "S"
    epsg = (32600 if hemi == "N" else 32700) + zone
    notes = []
    zones = np.unique(utm_zone(lat, lon))
    if len(zones) > 1 or (lat_lo < 0.0 <= lat_hi):
        notes.append(
            f"the survey spans UTM zones {', '.join(str(z) for z in zones)}"
            f"{' and both hemispheres' if lat_lo < 0.0 <= lat_hi else ''}; it is gridded in zone "
            f"{zone}{hemi}, its centre's"
        )
    return epsg, notes


def default_max_distance(survey: Survey) -> float:
    """How far from a sample a cell is still mapped: 8 % of the survey's larger side, at least 10 m."""
    span = float(np.ptp(survey.xy, axis=0).max())
    return max(MIN_MAX_DISTANCE_M, 0.08 * span)


def make_grid(
    survey: Survey, resolution: float, max_distance: float | None = None, utm: bool = True
) -> MapGrid:
    """The grid over the survey's samples, in its UTM zone (`utm`; else in its local frame, EPSG 0, for
    figures where pyproj is not installed), edges on multiples of `resolution`."""
    if not (math.isfinite(resolution) and resolution > 0):
        raise WorkbenchError(f"the resolution must be a number of metres above 0, not {resolution}")
    max_distance = default_max_distance(survey) if max_distance is None else float(max_distance)
    if not (math.isfinite(max_distance) and max_distance > 0):
        raise WorkbenchError(f"the mask distance must be above 0 m, not {max_distance}")
    lat, lon = survey.columns["lat"], survey.columns["lon"]
    if utm:
        from pyproj import Transformer

        epsg, notes = utm_epsg(lat, lon)
        e, n = Transformer.from_crs(4326, epsg, always_xy=True).transform(lon, lat)
    else:
        (epsg, notes), (e, n) = (0, []), (survey.columns["x"], survey.columns["y"])
    x0 = math.floor(float(np.min(e)) / resolution) * resolution
    y0 = math.floor(float(np.min(n)) / resolution) * resolution
    nx = int(math.floor((float(np.max(e)) - x0) / resolution)) + 1
    ny = int(math.floor((float(np.max(n)) - y0) / resolution)) + 1
    if nx * ny > MAX_CELLS:
        raise WorkbenchError(
            f"a {resolution:g} m grid over this survey has {nx * ny:,} cells (at most {MAX_CELLS:,}); "
            "give a coarser --resolution"
        )
    y1 = y0 + ny * resolution
    ee, nn = np.meshgrid(
        x0 + resolution * (np.arange(nx) + 0.5), y1 - resolution * (np.arange(ny) + 0.5)
    )
    if utm:
        glon, glat = Transformer.from_crs(epsg, 4326, always_xy=True).transform(ee, nn)
        lx, ly = LocalFrame(survey.lat0, survey.lon0).to_local(glat, glon)
    else:
        glat, glon = LocalFrame(survey.lat0, survey.lon0).to_latlon(ee, nn)
        lx, ly = ee, nn
    local_xy = np.column_stack([lx.ravel(), ly.ravel()])
    dist, _ = cKDTree(survey.xy).query(local_xy, distance_upper_bound=max_distance)
    mask = (dist <= max_distance).reshape(ny, nx)
    t = survey.columns["t"]
    span = (float(np.min(t)), float(np.max(t)))
    grid = MapGrid(
        epsg, x0, y1, resolution, nx, ny, glat, glon, mask, max_distance, span, notes=notes,
        local_xy=local_xy, distance=dist.reshape(ny, nx),
    )  # fmt: skip
    grid.mid_time = float(np.median(t))
    return grid


def project(grid: MapGrid, lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (degrees) as UTM easting/northing in the grid's zone."""
    from pyproj import Transformer

    e, n = Transformer.from_crs(4326, grid.epsg, always_xy=True).transform(lon, lat)
    return np.asarray(e), np.asarray(n)


def cell_of(grid: MapGrid, lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(row, col) of the cells holding positions (lat/lon): the inverse of the grid's geotransform."""
    e, n = project(grid, lat, lon)
    col = np.floor((e - grid.x0) / grid.resolution).astype(int)
    row = np.floor((grid.y1 - n) / grid.resolution).astype(int)
    return row, col


def true_north(grid: MapGrid) -> float:
    """Angle (deg, clockwise from the grid's north) of true north at the grid's centre (0 in a local grid)."""
    if grid.epsg == 0:
        return 0.0
    from pyproj import Transformer

    r, c = grid.ny // 2, grid.nx // 2
    lat, lon = float(grid.lat[r, c]), float(grid.lon[r, c])
    to_utm = Transformer.from_crs(4326, grid.epsg, always_xy=True)
    (e0, e1), (n0, n1) = to_utm.transform([lon, lon], [lat, lat + 1e-4])
    return math.degrees(math.atan2(e1 - e0, n1 - n0))


def layer_bands(model, pred: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The bands of one target from `SurveyModel.predict_grid`: mean, sd (predictive: what a new measurement
    would differ by) and mean_sd (the mean's own sd) for a scalar; east, north, their predictive sds, speed,
    its predictive sd, direction (its convention: wind FROM, current TO) and the target's mean_sd for a vector."""
    if "east" not in pred:
        return {"mean": pred["mean"], "sd": pred["std"], "mean_sd": pred["mean_std"]}
    vt = model.vector
    bands = {
        "east": pred["east"],
        "north": pred["north"],
        "east_sd": pred["east_std"],
        "north_sd": pred["north_std"],
        "speed": pred["mean"] if vt.aspect == "speed" else pred["speed"],
        "speed_sd": pred["std"] if vt.aspect == "speed" else pred["speed_std"],
        "dir": pred["mean"] if vt.aspect == "dir" else vt.direction(pred["east"], pred["north"]),
    }
    if vt.aspect == "dir":
        bands["dir_sd"] = pred["std"]
    bands[f"{vt.aspect}_mean_sd"] = pred["mean_std"]
    return bands


def relation_bands(model, xy: np.ndarray) -> dict[str, np.ndarray]:
    """A current related to a reference current: each place's `ratio` and `offset` (s) to its station,
    flood and ebb (`ebb_*`), with their sd (`names.RELATION_ATTRS`); none for any other model."""
    if getattr(model, "relation", None) is None or not len(xy):
        return {}
    from forcemap.host.workbench.terms.time_terms import relation_at

    maps = relation_at(model, xy)
    out = {}
    for tag in ("", "ebb_"):
        for key, band in (("ratio", "ratio"), ("offset_s", "offset")):
            out[tag + band] = maps[tag + key]
            out[tag + band + "_sd"] = maps[tag + key + "_sd"]
    return out


# a cell is left blank where a new measurement's predicted spread exceeds this share of the measured values' own
# spread: there the map predicts no better than the survey's average would
SD_SHARE = 1.0
# targets that cannot be at or below zero (depth below the surface)
POSITIVE = {"depth"}


def untrusted(grid: MapGrid, model, pred: dict[str, np.ndarray], keep: np.ndarray):
    """Which of the mapped cells `keep` a target leaves blank, and a note per reason: farther from the track
    than its blocked CV's held-out samples lay from their training data (an untested extrapolation), a
    predictive sd above SD_SHARE x the measured spread, or a positive quantity (depth) at or below zero."""
    cal, target = getattr(model, "calibration", None), model.target
    drop = np.zeros(int(keep.sum()), bool)
    notes = []
    if cal is not None and grid.distance is not None:
        far = _distance(grid, model, keep) > cal.reach_m
        if far.any():
            notes.append(
                f"{target}: {int(far.sum())} cells farther than {cal.reach_m:.0f} m from every sample left "
                "blank (90 % of the blocked CV's held-out samples lay within that of their training data: "
                "beyond it the map is an untested extrapolation)"
            )
        drop |= far
    sd = pred["std"]
    signal = float(model.signal_sd)
    vague = ~drop & (sd > SD_SHARE * signal) if signal > 0 else np.zeros_like(drop)
    if vague.any():
        notes.append(
            f"{target}: {int(vague.sum())} cells whose predictive sd exceeds {SD_SHARE:g} x the measured "
            f"values' own ({signal:.3g}) left blank: the map predicts no better there than their average"
        )
    drop |= vague
    if target in POSITIVE:
        low = ~drop & (pred["mean"] <= 0.0)
        if low.any():
            notes.append(
                f"{target}: {int(low.sum())} cells where the model's mean is at or above the surface "
                f"(<= 0 m, down to {float(pred['mean'][low].min()):.1f} m) left blank: it cannot be"
            )
        drop |= low
    return drop, notes


def _distance(grid: MapGrid, model, keep: np.ndarray) -> np.ndarray:
    """Each mapped cell's distance (m) to the nearest sample the model was fitted on (the grid's own
    distance, to every sample, where the model has them all)."""
    dist = grid.distance.ravel()[keep]  # type: ignore[union-attr]
    root, index = model.survey.origin
    if len(index) == root.n or grid.local_xy is None:
        return dist
    return np.fmax(dist, cKDTree(model.survey.xy).query(grid.local_xy[keep])[0])


def evaluate(grid: MapGrid, model) -> Layer:
    """A fitted `SurveyModel` on the grid's mapped cells (NaN elsewhere, and where `untrusted`), as a `Layer`,
    at the grid's time (`at`: a tide predicts there, a GP in time may have reverted to its mean, said in the
    layer's notes)."""
    keep = grid.mask.ravel()
    pred = model.predict_grid(grid.local_xy[keep], grid.at)
    bands = layer_bands(model, pred)
    drop, notes = untrusted(grid, model, pred, keep)
    if model.target == "depth":
        from forcemap.host.gis.surface import far_from_soundings

        sv = model.survey
        far = ~drop & far_from_soundings(grid, sv.xy[np.isfinite(sv.columns["depth"])])[keep]
        if far.any():
            notes.append(
                f"depth: {int(far.sum())} cells farther than {grid.max_distance:g} m from every "
                "sounding the map was fitted on (only spikes or a lost stretch near them) left blank"
            )
        drop |= far
    cells = np.flatnonzero(keep)[~drop]
    out = {}
    for name, values in bands.items():
        full = np.full(grid.ny * grid.nx, np.nan)
        full[cells] = values[~drop]
        out[name] = full.reshape(grid.ny, grid.nx)
    vt = model.vector if "east" in pred else None
    layer = Layer(model.target, list(model.terms), out, vt and vt.family, vt and vt.prefix)
    if model.target == "depth":
        from forcemap.host.gis.surface import depth_layer

        notes += depth_layer(grid, model, layer)
    relation = relation_bands(model, grid.local_xy[cells])  # a current on a reference current
    for name, values in relation.items():
        full = np.full(grid.ny * grid.nx, np.nan)
        full[cells] = values
        layer.bands[name] = full.reshape(grid.ny, grid.nx)
    rows = getattr(model, "rows", None)  # what the model left out for want of a reading
    notes = [f"{model.target}: {line}" for line in (rows.lines() if rows else [])] + notes
    held = held_notes(model.survey, getattr(model, "term_specs", ()))  # covariates at their median
    notes += [f"{model.target}: {n}" for n in held]
    if grid.at is not None:
        from forcemap.host.workbench.terms.time_terms import notes_at

        notes += [f"{model.target}: {n}" for n in notes_at(model.primary, model.survey, grid.at)]
    layer.notes, layer.calibration = notes, getattr(model, "calibration", None)
    return layer
