"""`forcemap grid`'s cost: a 43,000-sample survey's maps at 2 m over 1 km^2 (the issue's bound: 10 s).

    python -m bench.bench_grid [--samples 43000] [--resolution 2] [--work DIR] [--baseline]

(--work DIR of an earlier run reuses its table and fits.)

The synthetic river survey (`bench.synth_survey`, 1 Hz, depth-dependent current) flown for `--samples`
seconds, its track stretched to a 1 km x 1 km square. depth, current_speed and wind_speed are fitted
and recorded first (`forcemap fit`'s work, not timed as gridding); then `forcemap grid` runs as a user
runs it, from the table and the workspace, stage by stage through the API it calls: read the table,
rebuild the latest fits from their saved hyperparameters (and what a vector map shares: the flow
frame and the cross-flow component), evaluate every map on the grid's mapped cells (the gridding the
issue bounds), write the files. `--cli` also times the command end to end. CPU time is printed beside
wall time: on a shared machine the wall time mostly measures the neighbours.

`--baseline` grids once more in the same process the way it was done before the sine tables (the code
of that commit, kept in `features_formed`): every fast GP block's n x M features formed, then products
with them; and prints the ratio and the largest relative difference between the two grids.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import tempfile
import time
from pathlib import Path

import forcemap
import numpy as np
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


def stages(table: Path, resolution: float, work: Path) -> tuple[list, object]:
    """(stage, wall s, CPU s) of what `forcemap grid -o DIR` does, through the API it calls; the grid."""
    from forcemap.host.gis.contours import write_contours
    from forcemap.host.gis.geotiff import write_geotiff
    from forcemap.host.gis.netcdf import write_netcdf
    from forcemap.host.workbench.engine.model import small_blas

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
            "rebuild the latest fits (saved hyperparameters, a vector's flow frame and other component "
            "too: no optimiser)",
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
    return rows, grid


@contextlib.contextmanager
def features_formed():
    """Predictions as they were made before the sine tables, kept here as the baseline: the n x M features
    formed, the mean and the slow blocks' covariances as products with them, cosines by np.cos."""
    from forcemap.host.workbench.engine import fourier
    from forcemap.host.workbench.engine.hypersearch import term_inputs
    from forcemap.host.workbench.engine.model import Model

    def formed(self, Xc, mean_part, post, return_std):
        Phi = np.hstack(self.features(Xc))
        mu = Phi @ post["mu"] * self.y_scale_ + mean_part
        if not return_std:
            return mu, None
        term, (fcols, slow) = self.design_.fast[1], self.design_.fast_cols
        fourier.posterior_tables(term, self.design_.fast_cols, post)
        cos = [
            np.cos(u[:, None] * np.arange(2 * int(term.J[:, d].max()) + 1)[None, :])
            for d, u in enumerate(term.angles(term_inputs(term, Xc)))
        ]
        var = fourier.quadratic_form(term, None, post["table"], (cos, None))
        S, C = Phi[:, slow], post["cov_slow"]
        var += 2.0 * np.einsum("ij,ij->i", S @ C[:, fcols], Phi[:, fcols])
        var += np.einsum("ij,ij->i", S @ C[:, slow], S)
        return mu, np.sqrt(np.maximum(var * self.y_scale_**2, 0.0))

    fast = Model._predict_fast_rows
    Model._predict_fast_rows = formed
    try:
        yield
    finally:
        Model._predict_fast_rows = fast


def baseline(table: Path, resolution: float, grid) -> list[tuple[str, float, float]]:
    """The grid stage again with the features formed; the ratio, and how far its bands are from `grid`'s."""
    from forcemap.host.workbench.engine.model import small_blas

    survey = forcemap.read_survey(table)
    with small_blas():
        fits = [survey.latest_fit(t) for t in TARGETS]
        with features_formed():
            t0, c0 = time.perf_counter(), time.process_time()
            old = survey.grid(fits, resolution)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    worst = 0.0
    for t in TARGETS:
        for band, new in grid.layers[t].bands.items():
            ref = old.layers[t].bands[band]
            assert np.array_equal(np.isnan(ref), np.isnan(new))
            if band != "dir":
                worst = max(worst, float(np.nanmax(np.abs(new - ref)) / np.nanmax(np.abs(ref))))
    print(f"largest relative difference between the two grids' bands (dir aside): {worst:.1e}")
    return [("grid, before: the fast GP blocks' features formed (`--baseline`)", wall, cpu)]


def main_bench() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=43_000)
    ap.add_argument("--resolution", type=float, default=2.0)
    ap.add_argument("--work", type=Path, help="a folder to keep (and reuse) the table and its fits")
    ap.add_argument(
        "--cli", action="store_true", help="also time `forcemap grid -o DIR` as one command"
    )
    ap.add_argument(
        "--baseline",
        action="store_true",
        help="also grid with the features formed (before the tables)",
    )
    args = ap.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="bench_grid_"))
    work.mkdir(parents=True, exist_ok=True)
    table = fitted_table(work, args.samples)
    rows, grid = stages(table, args.resolution, work)
    if args.baseline:
        rows += baseline(table, args.resolution, grid)
        print(
            f"grid: {rows[-1][2] / rows[2][2]:.1f}x less CPU than before, {rows[-1][1] / rows[2][1]:.1f}x less wall"
        )
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
