"""Benchmark: forcemap's reduced-rank GP against scikit-learn's exact GaussianProcessRegressor.

Same data, same process, same spatially blocked folds. For each n: fit + predict (mean and std at every
sample) wall time for both, the ratio, and blocked 5-fold CV RMSE for both (hyperparameters refitted in every
fold, for both). The data are a synthetic 3-hour lawnmower survey of a river (bench.synth_survey), sampled at
the rate that gives n samples over the whole survey; the target is depth (scalar, sand bars ~80 m).
scikit-learn is run up to --sklearn-max samples (its cost grows as n^3; 43,000 samples would need a
15 GB kernel matrix and hours). Finally every target of a 43,000-sample survey is fitted by forcemap.

    python bench/bench_gp.py [--sizes 1000,2000,4000,8000,16000,43000] [--sklearn-max 4000] [--target depth]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # `bench.*` when run as a script

from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.cv import blocked_folds
from forcemap.host.workbench.model import Model, small_blas

from bench.synth_survey import simulate

SURVEY_S = 10_750.0  # 3 h: 43,000 samples at 4 Hz
BASELINE = ["const", "gp(position, matern32)"]


def survey(n: int, seed: int = 1) -> dict[str, np.ndarray]:
    cols = simulate([], seed, SURVEY_S, rate_hz=n / SURVEY_S)
    lat0, lon0 = cols["lat"].mean(), cols["lon"].mean()
    cols["x"], cols["y"] = LocalFrame(lat0, lon0).to_local(cols["lat"], cols["lon"])
    return cols


def forcemap_fit_predict(xy, y, xy_test):
    with small_blas():
        m = Model(BASELINE).fit({"position": xy}, y)
        return m.predict({"position": xy_test}, return_std=True)


def sklearn_fit_predict(xy, y, xy_test):
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    kernel = ConstantKernel(1.0) * Matern(length_scale=50.0, nu=1.5) + WhiteKernel(0.1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = GaussianProcessRegressor(kernel, normalize_y=True).fit(xy, y)
    return g.predict(xy_test, return_std=True)


def timed(fn, *args):
    t = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t


def blocked_cv_rmse(fn, xy, y) -> float:
    folds, _ = blocked_folds(xy, 5, seed=0)
    pred = np.empty_like(y)
    for f in np.unique(folds):
        test = folds == f
        pred[test] = fn(xy[~test], y[~test], xy[test])[0]
    return float(np.sqrt(np.mean((pred - y) ** 2)))


def all_targets(n: int) -> None:
    import tempfile
    from pathlib import Path

    from forcemap.host.workbench.table import load_survey
    from forcemap.host.workbench.targets import SurveyModel

    from bench.synth_survey import make_survey

    d = tempfile.mkdtemp()
    path = make_survey("river", [], 3, n / 4.0, d)
    path = Path(path)
    # make_survey samples at 1 Hz; rewrite at 4 Hz for a real 43k-sample table
    cols = simulate([], 3, n / 4.0, rate_hz=4.0)
    import csv

    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(list(cols))
        for row in zip(*cols.values(), strict=True):
            w.writerow([f"{v:.7f}" for v in row])
    t0 = time.perf_counter()
    s = load_survey(path)
    t_load = time.perf_counter() - t0
    targets = ["current_speed", "current_dir", "wind_speed", "wind_dir", "depth", "water_temp"]
    print(f"\nevery target of a {s.n}-sample survey (table read in {t_load:.1f} s):")
    total = 0.0
    with small_blas():
        for target in targets:
            t = time.perf_counter()
            SurveyModel(s, target).fit()
            dt = time.perf_counter() - t
            total += dt
            print(
                f"  {target:<14} {dt:6.1f} s  (components and flow frame shared with the other aspect)"
            )
    print(f"  total fit time for {len(targets)} targets: {total:.1f} s")


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--sizes", default="1000,2000,4000,8000,16000,43000")
    ap.add_argument("--sklearn-max", type=int, default=4000)
    ap.add_argument("--target", default="depth")
    ap.add_argument("--skip-all-targets", action="store_true")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at start")
    print(
        "forcemap: const + gp(position, matern32), Hilbert-space reduced rank (400 basis functions, doubled up to 2048 while the lengthscale is at the resolvable limit)"
    )
    print(
        "sklearn : ConstantKernel*Matern(nu=1.5) + WhiteKernel, normalize_y, default optimizer (exact GP)\n"
    )
    head = f"{'n':>6} {'forcemap s':>10} {'sklearn s':>10} {'speed-up':>9} {'CV RMSE fm':>11} {'CV RMSE sk':>11} {'fm/sk':>6}"
    print(head)
    print("-" * len(head))
    # warm-up: imports, BLAS and threadpoolctl's library scan are not part of either method's cost
    warm = survey(300)
    warm_xy = np.column_stack([warm["x"], warm["y"]])
    forcemap_fit_predict(warm_xy, warm[args.target], warm_xy)
    if sizes[0] <= args.sklearn_max:
        sklearn_fit_predict(warm_xy, warm[args.target], warm_xy)
    for n in sizes:
        cols = survey(n)
        xy, y = np.column_stack([cols["x"], cols["y"]]), cols[args.target]
        _, t_fm = timed(forcemap_fit_predict, xy, y, xy)
        cv_fm = blocked_cv_rmse(forcemap_fit_predict, xy, y)
        if n <= args.sklearn_max:
            _, t_sk = timed(sklearn_fit_predict, xy, y, xy)
            cv_sk = blocked_cv_rmse(sklearn_fit_predict, xy, y)
            print(
                f"{n:>6} {t_fm:>10.2f} {t_sk:>10.1f} {t_sk / t_fm:>8.0f}x {cv_fm:>11.4f} {cv_sk:>11.4f} {cv_fm / cv_sk:>6.3f}",
                flush=True,
            )
        else:
            print(
                f"{n:>6} {t_fm:>10.2f} {'skipped':>10} {'-':>9} {cv_fm:>11.4f} {'-':>11} {'-':>6}   (exact GP: n^3, infeasible)",
                flush=True,
            )
    print(
        f"\nload average at the end {os.getloadavg()[0]:.1f} (other work on the machine slows both methods)"
    )
    if not args.skip_all_targets:
        all_targets(43_000)


if __name__ == "__main__":
    main()
