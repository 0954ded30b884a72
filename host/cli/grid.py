"""`forcemap grid`: the workspace's latest maps on a grid in the survey's UTM zone, written for GIS."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from forcemap.host.cli.at_option import add_at, at_time
from forcemap.host.cli.common import (
    add_json,
    add_keep_outliers,
    add_output,
    add_quiet,
    add_reference_current,
    add_table,
    add_water_level,
    add_workspace_options,
    check_json_output,
    human,
    load_table,
    prepare_workspace,
    print_notes,
    teach,
    write_json,
)
from forcemap.host.errors import CliError
from forcemap.host.extras import install_hint

EPILOG = """\
The maps are the workspace's latest fits of each target (the rule of `report` and `plan`: the terms of
the latest `forcemap fit`, the paper's baseline where there is none), evaluated on a regular grid in the
survey's UTM zone (WGS 84). Cells farther than --mask-distance from every sample are left empty (nodata),
and so are a target's cells beyond its blocked CV's reach (an untested extrapolation), with a predictive
sd above the measured values' own, or a depth at or above the surface (each counted in a note). The sd
bands are predictive: what a new measurement would differ by (mean and noise), widened to cover 95 % of
blocked-CV held-out samples; the coverage is printed per target. A target that cannot be modelled (a
constant or empty column) is skipped with a note, and the others are written.

-o decides the format:
  maps.tif       a Cloud Optimized GeoTIFF per target (maps-depth.tif, ... with several targets): bands
                 mean, sd, mean_sd for a scalar; east, north, their sds, speed, speed_sd, dir and
                 speed_mean_sd (dir_mean_sd) for a vector
  maps.nc        one NetCDF file (CF-1.8) with every target, for xarray and ocean-model tools
  maps.geojson   contours of each scalar map (lon/lat), for web maps and Foxglove
  maps/          a folder: all three (TARGET.tif, maps.nc, TARGET-contours.geojson)

examples:
  forcemap grid survey.csv -o depth.tif --target depth --resolution 2
  forcemap grid survey.csv -o survey.nc
  forcemap grid survey.csv -o maps/ --json maps.json

Needs the extra: {install}. Surveys beyond UTM's limits (north of 84 N, south of 80 S)
or across the antimeridian are refused; one across a zone boundary is gridded in its centre's zone.
"""

DEFAULT_TARGETS = ("current_speed", "wind_speed", "depth", "water_temp")
FORMATS = {".tif": "geotiff", ".tiff": "geotiff", ".nc": "netcdf", ".geojson": "geojson"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    teach(parser, EPILOG.replace("{install}", install_hint("gis")))
    add_table(parser, several=True)
    add_output(
        parser, "OUT.tif, OUT.nc, OUT.geojson, or a folder for all three", required=True, type=Path
    )
    parser.add_argument(
        "--target",
        action="append",
        metavar="T",
        help="target to map (repeat, or comma-separated; default: current_speed, wind_speed, depth "
        "and water_temp, those the table has)",
    )
    parser.add_argument(
        "--resolution", type=float, default=5.0, metavar="M", help="cell size, m (default 5)"
    )
    parser.add_argument(
        "--mask-distance",
        type=float,
        metavar="M",
        help="leave cells empty farther than this from every sample (default: 8 %% of the survey's "
        "larger side, at least 10 m)",
    )
    add_at(parser, "the time the maps are for (the NetCDF's time, the GeoTIFF's time tag)")
    add_json(parser, "the grid and the files")
    add_quiet(parser)
    add_keep_outliers(parser)
    add_water_level(parser)
    add_reference_current(parser)
    add_workspace_options(parser, output=False)


def planned_files(
    out: Path, targets: list[str], scalars: list[str]
) -> dict[str, list[tuple[str, Path]]]:
    """format -> [(target or "", path)] that `-o out` asks for (contours: of the `scalars` only)."""
    fmt = FORMATS.get(out.suffix.lower())
    if fmt is None and out.suffix:
        raise CliError(
            f"-o {out}: give a .tif, .nc or .geojson file, or a folder (no suffix) for all three"
        )
    if fmt is None:
        return {
            "geotiff": [(t, out / f"{t}.tif") for t in targets],
            "netcdf": [("", out / "maps.nc")],
            "geojson": [(t, out / f"{t}-contours.geojson") for t in scalars],
        }
    if fmt == "netcdf":
        return {fmt: [("", out)]}
    if fmt == "geojson":
        if not scalars:
            raise CliError("contours are drawn of scalar maps (depth, water_temp, ...); give one")
        targets = scalars
    if len(targets) == 1:
        return {fmt: [(targets[0], out)]}
    return {fmt: [(t, out.with_name(f"{out.stem}-{t}{out.suffix}")) for t in targets]}


def _targets(args: argparse.Namespace, columns: list[str]) -> list[str]:
    if args.target:
        return list(
            dict.fromkeys(t.strip() for a in args.target for t in a.split(",") if t.strip())
        )
    found = [t for t in DEFAULT_TARGETS if t in columns or t.replace("_speed", "_east") in columns]
    if not found:
        raise CliError("the table has none of " + ", ".join(DEFAULT_TARGETS) + "; give --target")
    return found


def run(args: argparse.Namespace) -> int:
    from forcemap.host.cli.common import positive
    from forcemap.host.gis import need_gis

    need_gis("forcemap grid's maps")
    positive("--resolution", args.resolution)
    if args.mask_distance is not None:
        positive("--mask-distance", args.mask_distance)
    check_json_output(args)
    at_time(args)  # a bad --at is refused before any fit
    prepare_workspace(args)
    out = Path(args.output)
    if not out.suffix and out.exists() and not out.is_dir():
        raise CliError(f"-o {out} is a file; give a folder, or a .tif, .nc or .geojson file")
    return _run(args, out)


def _run(args: argparse.Namespace, out: Path) -> int:
    from forcemap.host.api import Survey
    from forcemap.host.gis.contours import write_contours
    from forcemap.host.gis.geotiff import write_geotiff
    from forcemap.host.gis.grid import utm_epsg
    from forcemap.host.gis.netcdf import write_netcdf
    from forcemap.host.outputs import check_output
    from forcemap.host.progress import note
    from forcemap.host.workbench.engine.model import small_blas

    progress = not args.quiet
    survey = Survey(load_table(args))
    utm_epsg(survey.table.columns["lat"], survey.table.columns["lon"])  # refused before the fits
    targets = _targets(args, survey.columns)
    scalars = [t for t in targets if survey.table.vector_target(t) is None]
    plan = planned_files(out, targets, scalars)
    if not out.suffix:
        out.mkdir(parents=True, exist_ok=True)
    for files in plan.values():
        for _, path in files:
            check_output(path, [args.table], force=args.force)
    with small_blas():
        fits, skipped = _latest_fits(survey, targets, progress)
        note(f"gridding at {args.resolution:g} m ...", progress)
        grid = survey.grid(fits, args.resolution, args.mask_distance, at_time(args))
    print_notes(survey.table)
    for t, why in skipped.items():
        print(f"note: skipped {t}: {why}; the other maps are written", file=sys.stderr)
    for n in grid.notes:
        print(f"note: {n}", file=sys.stderr)
    plan = {
        fmt: [(t, p) for t, p in files if not t or t in grid.layers] for fmt, files in plan.items()
    }
    written = []
    for fmt, files in plan.items():
        for target, path in files:
            layer = grid.layers.get(target)
            if fmt == "geotiff":
                written.append(write_geotiff(grid, layer, path))
            elif fmt == "netcdf":
                written.append(write_netcdf(grid, path))
            else:
                written.append(write_contours(grid, layer, path))
    write_json(args.json, _summary(grid, written, skipped))
    out = human(args)
    print(
        f"{grid.zone_name} (EPSG:{grid.epsg}), {grid.nx} x {grid.ny} cells of {grid.resolution:g} m, "
        f"{int(grid.mask.sum())} mapped, at {grid.time_iso()}"
        + ("" if grid.at is not None else " (the survey's mid-time; --at for another)"),
        file=out,
    )
    for t, layer in grid.layers.items():
        if layer.datum:
            print(f"{t}: {layer.datum}", file=out)
        if layer.calibration is not None:
            print(f"{t}: {layer.calibration.line()}", file=out)
    for p in written:
        print(f"wrote {p}", file=out)
    return 0


def _latest_fits(survey, targets: list[str], progress: bool) -> tuple[list, dict[str, str]]:
    """The workspace's latest fit of each target; a target that cannot be modelled (a constant or empty
    column) is skipped with why, and the others are still mapped."""
    from forcemap.host.progress import note
    from forcemap.host.workbench.errors import WorkbenchError

    fits, skipped = [], {}
    for t in targets:
        note(f"map of {t}: the workspace's latest fit ...", progress)
        try:
            fits.append(survey.latest_fit(t, progress))
        except WorkbenchError as exc:
            skipped[t] = str(exc)
    if not fits:
        raise CliError("no target could be mapped: " + "; ".join(skipped.values()))
    return fits, skipped


def _summary(grid, written: list[Path], skipped: dict[str, str]) -> dict:
    """The --json summary: the grid, each map's held-out coverage and blank cells, what was skipped."""
    import numpy as np

    return {
        "crs": f"EPSG:{grid.epsg}",
        "zone": grid.zone_name,
        "resolution_m": grid.resolution,
        "shape": [grid.ny, grid.nx],
        "mapped_cells": int(grid.mask.sum()),
        "mask_distance_m": grid.max_distance,
        "time": grid.time_iso(),
        "targets": {t: " + ".join(layer.terms) for t, layer in grid.layers.items()},
        "coverage95": {
            t: layer.calibration.to_json()
            for t, layer in grid.layers.items()
            if layer.calibration is not None
        },
        "blank_cells": {
            t: int((grid.mask & ~np.isfinite(next(iter(layer.bands.values())))).sum())
            for t, layer in grid.layers.items()
        },  # fmt: skip
        "skipped": skipped,
        "files": [str(p) for p in written],
    }
