"""Benchmark: forcemap's reduced-rank GP against scikit-learn's exact GaussianProcessRegressor.

Same data, same process, same spatially blocked folds. For each n: fit + predict (mean and std at every
sample) wall time for both, the ratio, and blocked 5-fold CV RMSE for both (hyperparameters refitted in every
fold, for both). The data are a synthetic 3-hour lawnmower survey of a river (bench.synth_survey), sampled at
the rate that gives n samples over the whole survey; the target is depth (scalar, sand bars ~80 m).
scikit-learn is run up to --sklearn-max samples (its cost grows as n^3; 43,000 samples would need a
15 GB kernel matrix and hours). Finally every target of a 43,500-sample survey (vectors through their
components) is fitted as `forcemap fit` does, with its blocked CV and the mean and predictive sd on a
10,000-node grid, each in a fresh process: wall time and peak RSS per target, against the budget of 5 s and
1 GiB; with --baseline-src, the same for another checkout of the code and the largest relative difference
between the two versions' results.

    python bench/bench_gp.py [--sizes 1000,2000,4000,8000,16000,43000] [--sklearn-max 4000] [--target depth]
    python bench/bench_gp.py --targets-only --baseline-src /tmp/before   # git worktree add /tmp/before d3cd597
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


TARGETS = ["current_speed", "current_dir", "wind_speed", "wind_dir", "depth", "water_temp"]
BUDGET_S, BUDGET_MB = 5.0, 1024.0


def write_table(n: int, out_dir: str) -> Path:
    """A 3-hour survey at 4 Hz (bench.synth_survey), `n` samples, as a CSV table."""
    import csv

    cols = simulate([], 3, n / 4.0, rate_hz=4.0)
    path = Path(out_dir) / "survey.csv"
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


def run_target(table: Path, target: str, save: Path, pythonpath: str | None) -> dict:
    """`bench/fit_one_target.py` in a fresh process: fit, blocked CV, 10,000-node map; time and peak RSS."""
    import json
    import subprocess
    import sys

    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath + os.pathsep + env.get("PYTHONPATH", "")
    script = Path(__file__).with_name("fit_one_target.py")
    cmd = [sys.executable, str(script), str(table), target, "--save", str(save)]
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


def all_targets(n: int, baseline_src: str | None) -> None:
    """Every target of an n-sample survey with its blocked CV and the predictive sd on a 10,000-node grid,
    each in a fresh process; with `baseline_src` also the code before, and how far the results differ."""
    import tempfile

    d = tempfile.mkdtemp()
    table = write_table(n, d)
    old = code_path(baseline_src, d) if baseline_src else None
    print(
        f"\nevery target of a {n}-sample survey: fit + blocked 5-fold CV + mean and sd on 10,000 nodes"
    )
    head = f"{'target':<14} {'basis':>5} {'time s':>7} {'cpu s':>6} {'peak MB':>8} {'CV RMSE':>9}"
    if old:
        head += (
            f" {'before s':>9} {'cpu s':>6} {'before MB':>10} {'CV RMSE':>9} {'cpu speed-up':>12}"
            f" {'max rel diff':>13}"
        )
    print(head)
    print("-" * len(head))
    worst_t, worst_m = 0.0, 0.0
    for target in TARGETS:
        new = run_target(table, target, Path(d) / f"{target}-new.npz", None)
        worst_t, worst_m = max(worst_t, new["total_s"]), max(worst_m, new["peak_rss_mb"])
        line = (
            f"{target:<14} {new['n_basis']:>5} {new['total_s']:>7.2f} {new['cpu_s']:>6.2f} "
            f"{new['peak_rss_mb']:>8.0f} {new['cv_rmse']:>9.6f}"
        )
        if old:
            before = run_target(table, target, Path(d) / f"{target}-old.npz", old)
            diff = agreement(Path(d) / f"{target}-old.npz", Path(d) / f"{target}-new.npz")
            line += (
                f" {before['total_s']:>9.2f} {before['cpu_s']:>6.2f} {before['peak_rss_mb']:>10.0f}"
                f" {before['cv_rmse']:>9.6f} {before['cpu_s'] / new['cpu_s']:>11.2f}x {diff:>13.1e}"
            )
        print(line, flush=True)
    ok = worst_t <= BUDGET_S and worst_m <= BUDGET_MB
    print(
        f"load average {os.getloadavg()[0]:.1f} (time s is wall clock; cpu s, the process's CPU time, is what "
        "a busy machine does not inflate)\n"
        f"worst target: {worst_t:.2f} s, {worst_m:.0f} MB peak RSS "
        f"(budget {BUDGET_S:.0f} s, {BUDGET_MB:.0f} MB): {'within' if ok else 'OVER'}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--sizes", default="1000,2000,4000,8000,16000,43000")
    ap.add_argument("--sklearn-max", type=int, default=4000)
    ap.add_argument("--target", default="depth")
    ap.add_argument("--skip-all-targets", action="store_true")
    ap.add_argument("--targets-only", action="store_true", help="only the every-target table")
    ap.add_argument(
        "--targets-n", type=int, default=43_500, help="samples of the every-target survey"
    )
    ap.add_argument(
        "--baseline-src",
        help="a checkout of the code to compare with (e.g. `git worktree add /tmp/before d3cd597`)",
    )
    args = ap.parse_args()
    if args.targets_only:
        all_targets(args.targets_n, args.baseline_src)
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
        all_targets(args.targets_n, args.baseline_src)


if __name__ == "__main__":
    main()
