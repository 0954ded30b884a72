"""`forcemap grid`'s cost: a 43,000-sample survey's maps at 2 m over 1 km^2 (the issue's bound: 10 s).

    python -m bench.bench_grid [--samples 43000] [--resolution 2] [--work DIR]

(--work DIR of an earlier run reuses its table and fits.)

The synthetic river survey (`bench.synth_survey`, 1 Hz, depth-dependent current) flown for `--samples`
seconds, its track stretched to a 1 km x 1 km square. depth, current_speed and wind_speed are fitted
and recorded first (`forcemap fit`'s work, not timed as gridding); then `forcemap grid` runs as a user
runs it, from the table and the workspace: load the table, rebuild the latest fits from their saved
hyperparameters, fit what a vector map shares (flow frame, cross-flow component), evaluate every map on
the grid's mapped cells, write. Timed twice: to one NetCDF file, and to a folder (GeoTIFF per target,
NetCDF, contours).
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


def main_bench() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=43_000)
    ap.add_argument("--resolution", type=float, default=2.0)
    ap.add_argument("--work", type=Path, help="a folder to keep (and reuse) the table and its fits")
    args = ap.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="bench_grid_"))
    work.mkdir(parents=True, exist_ok=True)
    table = fitted_table(work, args.samples)
    rows = []
    for label, out in (
        ("one NetCDF", work / "maps.nc"),
        ("folder: tif + nc + geojson", work / "maps"),
    ):
        t0, c0 = time.perf_counter(), time.process_time()
        rc = main(["grid", str(table), "-o", str(out), "--resolution", f"{args.resolution:g}",
                   "--target", ",".join(TARGETS), "--quiet", "--force", "--json", str(work / "g.json")])  # fmt: skip
        assert rc == 0
        rows.append((label, time.perf_counter() - t0, time.process_time() - c0))
    g = json.loads((work / "g.json").read_text())
    print(
        f"grid {g['shape'][1]} x {g['shape'][0]} cells of {args.resolution:g} m "
        f"({g['mapped_cells']} mapped), {g['zone']}; load average {os.getloadavg()[0]:.1f} "
        f"on {os.cpu_count()} cores"
    )
    print("| output | wall time (s) | CPU time (s) |\n|---|---|---|")
    for label, dt, cpu in rows:
        print(f"| {label} | {dt:.1f} | {cpu:.1f} |")


if __name__ == "__main__":
    main_bench()
