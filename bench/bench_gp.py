"""Benchmark: forcemap's reduced-rank GP against scikit-learn's exact GaussianProcessRegressor.

Same data, same process, same spatially blocked folds. For each n: fit + predict (mean and std at every
sample) wall time for both, the ratio, and blocked 5-fold CV RMSE for both (hyperparameters refitted in every
fold, for both). The data are a synthetic 3-hour lawnmower survey of a river (bench.synth_survey), sampled at
the rate that gives n samples over the whole survey; the target is depth (scalar, sand bars ~80 m).
scikit-learn is run up to --sklearn-max samples (its cost grows as n^3; 43,000 samples would need a
15 GB kernel matrix and hours). Finally every target (vectors through their components) of surveys of 4,000,
43,500 and 1,000,000 samples (the last a long survey at 1 Hz, 11.6 days, as Parquet; current_speed and depth) is
fitted as `forcemap fit` does (spikes, fit, blocked CV and its calibration, depth's crossline error), then mapped,
each in a fresh process: the CPU seconds of fit + CV over one plain Gram product (n rows, 1,600 functions: the
survey's largest basis, timed in the same process, so that a loaded machine moves both alike), and peak RSS,
against the budgets (43,500: 2 Gram products and 1 GiB; 10^6: fit + CV + a 2 m grid in 60 s of CPU and 4 GiB).
The same run with the Gram tables summed directly (as without finufft) and the largest relative difference of
the results (hyperparameters, held-out predictions and bounds, map mean and sd) are printed beside it; with
--baseline-src, another checkout's CPU too.

    python bench/bench_gp.py [--sizes 1000,2000,4000,8000,16000,43000] [--sklearn-max 4000] [--target depth]
    python bench/bench_gp.py --targets-only [--targets-n 4000,43500,1000000] [--baseline-src /tmp/before]
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
from forcemap.host.workbench.engine.model import Model, small_blas
from forcemap.host.workbench.validation.cv import blocked_folds

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


TARGETS = ["current_speed", "current_dir", "wind_speed", "wind_dir", "depth", "water_temp"]
BIG_TARGETS = ["current_speed", "depth"]
# the budgets: every target of the 43,500-sample survey, fit + CV, within 2 plain Gram products and
# 1 GiB; a million rows (current, depth), fit + CV + a 2 m grid, within 60 s of CPU and 4 GiB
BUDGET_GRAMS, BUDGET_MB, BUDGET_N = 2.0, 1024.0, 43_500
BIG_N, BIG_BUDGET_S, BIG_BUDGET_MB = 1_000_000, 60.0, 4096.0
UNIT_M = 1600  # the survey's largest basis (depth's): the Gram product every target is counted in


def write_table(n: int, out_dir: str) -> Path:
    """A survey of `n` samples at 4 Hz (bench.synth_survey) as a CSV table; from BIG_N on, a long survey at
    1 Hz written a day at a time as Parquet row groups (`write_long_survey`: 10^6 rows are 11.6 days)."""
    import csv

    from bench.synth_survey import write_long_survey

    if n >= BIG_N:
        return write_long_survey(Path(out_dir) / f"survey-{n}.parquet", n)
    cols = simulate([], 3, n / 4.0, rate_hz=4.0)
    path = Path(out_dir) / f"survey-{n}.csv"
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(list(cols))
        for row in zip(*cols.values(), strict=True):
            w.writerow([f"{v:.7f}" for v in row])
    return path


def code_path(src: str, out_dir: str) -> str:
    """A directory that makes `import forcemap` load the checkout `src` (for the before/after table)."""
    pkg = Path(out_dir) / "baseline" / "forcemap"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    for sub in ("firmware_bridge", "protocol", "host", "sim_devices"):
        (pkg / sub).symlink_to(Path(src).resolve() / sub)
    return str(pkg.parent)


def run_target(table: Path, target: str, save: Path, pythonpath: str | None, *extra: str) -> dict:
    """`bench/fit_one_target.py` in a fresh process: fit_target, then the map; CPU, the Gram unit, peak RSS."""
    import json
    import subprocess
    import sys

    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath + os.pathsep + env.get("PYTHONPATH", "")
    script = Path(__file__).with_name("fit_one_target.py")
    cmd = [sys.executable, str(script), str(table), target, "--save", str(save), *extra]
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def agreement(a: Path, b: Path) -> float:
    """Largest relative difference between two runs' saved results (hyperparameters, CV, map mean and sd)."""
    x, y = np.load(a), np.load(b)
    worst = 0.0
    for k in x.files:
        u, v = x[k], y[k]
        scale = float(np.nanmax(np.abs(u))) or 1.0
        worst = max(worst, float(np.nanmax(np.abs(u - v))) / scale)
    return worst


def all_targets(
    sizes: list[int], targets: list[str], baseline_src: str | None, compare: bool
) -> None:
    """Every target of an n-sample survey as `forcemap fit` runs it (fit_target: spikes, fit, blocked CV and
    its calibration, the crossline error for depth), then the mean and sd on a grid (2 m cells from BIG_N on,
    else 100 x 100 nodes), each in a fresh process: CPU seconds of fit + CV over one plain Gram product of
    n rows and UNIT_M functions timed in the same process, and peak RSS. With `compare`, the same run with the
    tables summed directly (as without finufft) and the largest relative difference of the results; with
    `baseline_src`, another checkout's run and its CPU."""
    import tempfile

    d = tempfile.mkdtemp()
    old = code_path(baseline_src, d) if baseline_src else None
    for n in sizes:
        table = write_table(n, d)
        big = n >= BIG_N
        names = [t for t in targets if t in BIG_TARGETS] if big else targets
        grid = ["--grid-m", "2"] if big else []
        print(
            f"\nevery target of a {n:,}-sample survey: fit + blocked 5-fold CV (as `forcemap fit`), then the map "
            f"({'2 m cells' if big else '100 x 100 nodes'}); one plain Gram product = {n:,} x {UNIT_M}^2"
        )
        head = (
            f"{'target':<14} {'basis':>5} {'fit+CV s':>8} {'grid s':>6} {'Gram s':>6} {'Grams':>6} "
            f"{'own-m Grams':>11} {'peak MB':>8} {'CV RMSE':>9}"
        )
        if compare and not big:
            head += f" {'direct s':>8} {'max rel diff':>12}"
        if old:
            head += f" {'before s':>8} {'before Grams':>12} {'before MB':>9}"
        print(head)
        print("-" * len(head))
        worst_g, worst_m, worst_s = 0.0, 0.0, 0.0
        for target in names:
            new = run_target(
                table,
                target,
                Path(d) / f"{target}-{n}-new.npz",
                None,
                *grid,
                "--unit-m",
                str(UNIT_M),
            )
            unit = new["unit_gram_s"]
            grams = new["fit_cv_cpu_s"] / unit
            worst_g = max(worst_g, grams)
            worst_m = max(worst_m, new["peak_rss_mb"])
            worst_s = max(worst_s, new["cpu_s"])
            line = (
                f"{target:<14} {new['n_basis']:>5} {new['fit_cv_cpu_s']:>8.2f} {new['grid_cpu_s']:>6.2f} "
                f"{unit:>6.2f} {grams:>6.2f} {new['fit_cv_cpu_s'] / new['gram_s']:>11.1f} "
                f"{new['peak_rss_mb']:>8.0f} {new['cv_rmse']:>9.6f}"
            )
            if compare and not big:
                dense = run_target(
                    table, target, Path(d) / f"{target}-{n}-direct.npz", None, *grid, "--direct"
                )
                diff = agreement(
                    Path(d) / f"{target}-{n}-direct.npz", Path(d) / f"{target}-{n}-new.npz"
                )
                line += f" {dense['fit_cv_cpu_s']:>8.2f} {diff:>12.1e}"
            if old:
                before = run_target(table, target, Path(d) / f"{target}-{n}-old.npz", old, *grid)
                line += (
                    f" {before['fit_cv_cpu_s']:>8.2f} {before['fit_cv_cpu_s'] / unit:>12.2f}"
                    f" {before['peak_rss_mb']:>9.0f}"
                )
            print(line, flush=True)
        if big:
            ok = worst_s <= BIG_BUDGET_S and worst_m <= BIG_BUDGET_MB
            verdict = (
                f"worst: {worst_s:.1f} s of CPU (fit + CV + grid), {worst_m:.0f} MB peak RSS (budget "
                f"{BIG_BUDGET_S:.0f} s, {BIG_BUDGET_MB:.0f} MB): {'within' if ok else 'OVER'}"
            )
        else:
            ok = worst_g <= BUDGET_GRAMS and worst_m <= BUDGET_MB
            judged = (
                f"{'within' if ok else 'OVER'}"
                if n == BUDGET_N
                else f"judged at n = {BUDGET_N:,} only"
            )
            verdict = (
                f"worst: {worst_g:.2f} Gram products (fit + CV), {worst_m:.0f} MB peak RSS (budget "
                f"{BUDGET_GRAMS:.0f}, {BUDGET_MB:.0f} MB): {judged}"
            )
        print(f"load average {os.getloadavg()[0]:.1f}; {verdict}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--sizes", default="1000,2000,4000,8000,16000,43000")
    ap.add_argument("--sklearn-max", type=int, default=4000)
    ap.add_argument("--target", default="depth")
    ap.add_argument("--skip-all-targets", action="store_true")
    ap.add_argument("--targets-only", action="store_true", help="only the every-target tables")
    ap.add_argument(
        "--targets-n",
        default="4000,43500,1000000",
        help="sizes of the every-target surveys (from 1,000,000 on: current_speed and depth, 2 m grid)",
    )
    ap.add_argument(
        "--targets", default=",".join(TARGETS), help="targets of the every-target tables"
    )
    ap.add_argument(
        "--no-compare",
        action="store_true",
        help="skip the run with the tables summed directly (as without finufft) and its difference",
    )
    ap.add_argument(
        "--baseline-src",
        help="a checkout of the code to compare with (e.g. `git worktree add /tmp/before d3cd597`)",
    )
    args = ap.parse_args()
    every = ([int(v) for v in args.targets_n.split(",")], args.targets.split(","))
    if args.targets_only:
        all_targets(*every, args.baseline_src, not args.no_compare)
        return
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
        all_targets(*every, args.baseline_src, not args.no_compare)


if __name__ == "__main__":
    main()
