"""`forcemap grid`'s cost: a 43,000-sample survey's maps at 2 m over 1 km^2 (the issue's bound: 10 s).

    python -m bench.bench_grid [--samples 43000] [--resolution 2] [--work DIR]

(--work DIR of an earlier run reuses its table and fits.)

The synthetic river survey (`bench.synth_survey`, 1 Hz, depth-dependent current) flown for `--samples`
seconds, its track stretched to a 1 km x 1 km square. depth, current_speed and wind_speed are fitted
and recorded first (`forcemap fit`'s work, not timed as gridding); then `forcemap grid` runs as a user
runs it, from the table and the workspace, stage by stage through the API it calls: read the table,
rebuild the latest fits from their saved hyperparameters (and fit what a vector map shares: the flow
frame and the cross-flow component), evaluate every map on the grid's mapped cells (the gridding the
issue bounds), write the files. `--cli` also times the command end to end. CPU time is printed beside
wall time: on a shared machine the wall time mostly measures the neighbours.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import forcemap
from forcemap.host.cli import main

from bench.synth_survey import HALF_LENGTH, HALF_WIDTH, LAT0, LON0, make_survey

TARGETS = ("depth", "current_speed", "wind_speed")
SIDE_M = 1000.0


def square() -> dict:
    """`make_survey` extras stretching the 600 m x 150 m reach to a SIDE_M square about its centre (the
    fields stretch with it)."""
    kx, ky = SIDE_M / (2 * HALF_LENGTH), SIDE_M / (2 * HALF_WIDTH)
    return {
        "lat": lambda c: LAT0 + (c["lat"] - LAT0) * ky,
        "lon": lambda c: LON0 + (c["lon"] - LON0) * kx,
    }


def fitted_table(work: Path, samples: int) -> Path:
    """The survey's table with its fits recorded; a --work folder of an earlier run is reused."""
    table = work / "survey.csv"
    history = work / "survey.csv.forcemap" / "history.json"
    if history.exists() and {h["target"] for h in json.loads(history.read_text())} >= set(TARGETS):
        print(f"{forcemap.read_survey(table).n} samples; the fits in {work} reused")
        return table
    make_survey("river", ["depth_current"], 7, float(samples), work, extra=square())
    survey = forcemap.read_survey(table)
    t0 = time.perf_counter()
    for target in TARGETS:
        survey.fit(target, record=True)
    dt = time.perf_counter() - t0
    print(f"{survey.n} samples; fitted {', '.join(TARGETS)} in {dt:.1f} s (not timed below)")
    return table


def stages(table: Path, resolution: float, work: Path) -> list[tuple[str, float, float]]:
    """(stage, wall s, CPU s) of what `forcemap grid -o DIR` does, through the API it calls."""
    from forcemap.host.gis.contours import write_contours
    from forcemap.host.gis.geotiff import write_geotiff
    from forcemap.host.gis.netcdf import write_netcdf
    from forcemap.host.workbench.model import small_blas

    out, rows = work / "maps", []
    out.mkdir(exist_ok=True)

    def timed(label, f):
        t0, c0 = time.perf_counter(), time.process_time()
        value = f()
        rows.append((label, time.perf_counter() - t0, time.process_time() - c0))
        return value

    with small_blas():
        survey = timed("read the table", lambda: forcemap.read_survey(table))
        fits = timed(
            "rebuild the latest fits (saved hyperparameters; a vector's flow frame and cross-flow "
            "component fitted)",
            lambda: [survey.latest_fit(t) for t in TARGETS],
        )
        grid = timed(
            "**grid: every map on the mapped cells**", lambda: survey.grid(fits, resolution)
        )
    timed(
        "write: a GeoTIFF per target, the NetCDF, the depth contours",
        lambda: (
            [write_geotiff(grid, grid.layers[t], out / f"{t}.tif") for t in TARGETS],
            write_netcdf(grid, out / "maps.nc"),
            write_contours(grid, grid.layers["depth"], out / "depth.geojson"),
        ),
    )
    print(
        f"grid {grid.nx} x {grid.ny} cells of {resolution:g} m ({int(grid.mask.sum())} mapped), "
        f"{grid.zone_name}"
    )
    return rows


def main_bench() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=43_000)
    ap.add_argument("--resolution", type=float, default=2.0)
    ap.add_argument("--work", type=Path, help="a folder to keep (and reuse) the table and its fits")
    ap.add_argument(
        "--cli", action="store_true", help="also time `forcemap grid -o DIR` as one command"
    )
    args = ap.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="bench_grid_"))
    work.mkdir(parents=True, exist_ok=True)
    table = fitted_table(work, args.samples)
    rows = stages(table, args.resolution, work)
    if args.cli:
        t0, c0 = time.perf_counter(), time.process_time()
        rc = main(["grid", str(table), "-o", str(work / "cli"), "--resolution", f"{args.resolution:g}",
                   "--target", ",".join(TARGETS), "--quiet", "--force"])  # fmt: skip
        assert rc == 0
        rows.append(
            (
                "`forcemap grid -o DIR`, end to end",
                time.perf_counter() - t0,
                time.process_time() - c0,
            )
        )
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print("| stage | wall time (s) | CPU time (s) |\n|---|---:|---:|")
    for label, dt, cpu in rows:
        print(f"| {label} | {dt:.1f} | {cpu:.1f} |")


if __name__ == "__main__":
    main_bench()
