"""One target of a survey the way `forcemap fit` does it, plus the map: fit, blocked 5-fold CV with 95 %
intervals, and the mean and predictive sd on a 100 x 100 = 10,000-node grid over the survey. Prints one JSON
line: the wall time of those steps (the table's reading is not counted), the process's peak RSS, and the
results (for comparing two versions of the code). Run by `bench_gp.py --targets` in a fresh process per
target, so that each peak RSS is that target's own.

    python bench/fit_one_target.py TABLE TARGET [--save OUT.npz]
"""

from __future__ import annotations

import argparse
import json
import resource
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("table")
    ap.add_argument("target")
    ap.add_argument("--save")
    args = ap.parse_args()
    from forcemap.host.workbench import fitting
    from forcemap.host.workbench.model import small_blas
    from forcemap.host.workbench.table import load_survey
    from forcemap.host.workbench.targets import SurveyModel

    survey = load_survey(args.table)
    lo, hi = survey.xy.min(axis=0), survey.xy.max(axis=0)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 100), np.linspace(lo[1], hi[1], 100))
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    t0, c0 = time.perf_counter(), time.process_time()
    with small_blas():
        try:  # as fit_target: the folds of the rows the model is fitted on (with the target, spikes out)
            from forcemap.host.workbench.target_rows import target_rows

            clean = target_rows(survey, args.target).survey
        except ImportError:
            try:
                from forcemap.host.workbench.spikes import without_spikes

                clean = without_spikes(survey, args.target)[0]
            except ImportError:
                clean = survey
        folds = fitting.make_folds(clean, "blocked")
        try:  # the Gram matrices accumulate fold by fold (this version's fit_target does it)
            from forcemap.host.workbench.survey_fits import survey_fits

            survey_fits(clean).grams.plan = folds
        except (ImportError, AttributeError):
            pass
        sm = SurveyModel(survey, args.target).fit()
        t1 = time.perf_counter()
        cv = sm.cv(folds)
        t2 = time.perf_counter()
        out = sm.predict_grid(grid)
    t3, c3 = time.perf_counter(), time.process_time()
    basis = sm.primary.n_basis_
    print(
        json.dumps(
            {
                "target": args.target,
                "n": survey.n,
                "fit_s": t1 - t0,
                "cv_s": t2 - t1,
                "grid_s": t3 - t2,
                "total_s": t3 - t0,
                "cpu_s": c3 - c0,
                "rss_before_mb": rss0,
                "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                "n_basis": max(basis.values()) if basis else 0,
                "cv_rmse": cv.rmse,
                "coverage95": cv.coverage95,
            }
        ),
        flush=True,
    )
    if args.save:
        np.savez(
            args.save,
            theta=sm.primary.theta_,
            cv=cv.predicted,
            lower=cv.lower,
            mean=out["mean"],
            std=out["std"],
        )


if __name__ == "__main__":
    main()
