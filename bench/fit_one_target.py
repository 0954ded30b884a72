"""One target of a survey the way `forcemap fit` runs it (`fitting.fit_target`: spikes left out, the fit, its
blocked 5-fold CV with 95 % intervals and the band's calibration, the crossline error for depth), then the mean and
predictive sd on a grid over the survey (`--grid-m M`: M-metre cells over its extent, else 100 x 100 nodes).
Prints one JSON line: the CPU seconds of the fit + CV and of the grid, the process's peak RSS, the basis, the CV
error, and the CPU seconds of one plain Gram product n m^2 (n rows, m the target's largest basis, and m = `--unit-m`
if given) timed in the same process: the figure a busy machine does not move. Run by `bench_gp.py` in a fresh
process per target, so that each peak RSS is that target's own.

    python bench/fit_one_target.py TABLE TARGET [--save OUT.npz] [--grid-m 2] [--unit-m 1600] [--direct]
"""

from __future__ import annotations

import argparse
import json
import resource
import time

import numpy as np

GRAM_ROWS = 65_536  # the plain Gram product is timed on this many rows and scaled by n / rows (flops are linear in n)


def gram_product_s(n: int, m: int) -> float:
    """CPU seconds of one plain Gram product F'F of an n x m matrix on one BLAS thread, in chunks of 4,096
    rows (a million rows of 1,600 features would be 12.8 GB), timed on GRAM_ROWS rows (one chunk over and over:
    a small n is timed as long as a large one) and scaled by n / GRAM_ROWS."""
    from forcemap.host.workbench.engine.evidence import small_blas

    F = np.random.default_rng(0).standard_normal((4096, m))
    G = np.zeros((m, m))
    with small_blas():
        G += F.T @ F  # warm-up: BLAS's first call
        c = time.process_time()
        for _ in range(GRAM_ROWS // 4096):
            G += F.T @ F
        return (time.process_time() - c) * n / GRAM_ROWS


def grid_of(survey, grid_m: float | None) -> np.ndarray:
    lo, hi = survey.xy.min(axis=0), survey.xy.max(axis=0)
    if grid_m:
        axes = [np.arange(a, b + grid_m, grid_m) for a, b in zip(lo, hi, strict=True)]
    else:
        axes = [np.linspace(a, b, 100) for a, b in zip(lo, hi, strict=True)]
    gx, gy = np.meshgrid(*axes)
    return np.column_stack([gx.ravel(), gy.ravel()])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("table")
    ap.add_argument("target")
    ap.add_argument("--save")
    ap.add_argument(
        "--grid-m", type=float, help="grid cells of this many metres (default 100 x 100 nodes)"
    )
    ap.add_argument("--unit-m", type=int, help="also the Gram product with this basis size")
    ap.add_argument(
        "--direct", action="store_true", help="the tables summed directly, as without finufft"
    )
    args = ap.parse_args()
    import contextlib

    from forcemap.host.workbench.engine.model import small_blas
    from forcemap.host.workbench.fits import fit as fitting
    from forcemap.host.workbench.survey.table import load_survey

    try:
        from forcemap.host.workbench.engine import nufft
        direct = nufft.direct() if args.direct else contextlib.nullcontext()
    except ImportError:  # a checkout before the NUFFT
        direct = contextlib.nullcontext()
    c_load = time.process_time()
    survey = load_survey(args.table)
    load_s = time.process_time() - c_load
    grid = grid_of(survey, args.grid_m)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    with small_blas(), direct:
        c0 = time.process_time()
        res = fitting.fit_target(
            survey, args.target, ["const", "gp(position, matern32)"], progress=False
        )
        c1 = time.process_time()
        out = res.model.predict_grid(grid)
        c2 = time.process_time()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    sm = res.model
    basis = sm.primary.n_basis_
    m = max(basis.values()) if basis else 1
    unit = gram_product_s(survey.n, m)
    result = {
        "target": args.target,
        "n": survey.n,
        "load_cpu_s": load_s,
        "fit_cv_cpu_s": c1 - c0,
        "grid_cpu_s": c2 - c1,
        "grid_nodes": len(grid),
        "cpu_s": c2 - c0,
        "gram_s": unit,
        "gram_m": m,
        "rss_before_mb": rss0,
        "peak_rss_mb": peak,
        "n_basis": m,
        "cv_rmse": res.cv.rmse,
        "coverage95": res.cv.coverage95,
    }
    if args.unit_m:
        result["unit_gram_s"] = gram_product_s(survey.n, args.unit_m)
    print(json.dumps(result), flush=True)
    if args.save:
        np.savez(
            args.save,
            theta=sm.primary.theta_,
            cv=res.cv.predicted,
            lower=res.cv.lower,
            mean=out["mean"],
            std=out["std"],
        )


if __name__ == "__main__":
    main()
