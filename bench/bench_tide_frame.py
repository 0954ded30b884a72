"""A tide on a speed target: the flow frame's axis at each place against one axis for the whole survey
(bench/RESULTS.md, "A tide on a speed target and its frame").

    python -m bench.bench_tide_frame CASE [--terms "" tide] [--target current_speed]

`fit`'s crossline RMSE (each time stretch held out, scored where the boat comes back) and blocked-CV RMSE
with the baseline plus each set of terms, twice: with the frame as forcemap builds it when the terms hold a
tide or a seiche (the major axis of the velocity over the cycle at each place, `flow_axis.axis_frame`), and
with the survey's overall axis (`flow_axis.reference`) at every place, patched in for the second run. A
uniform tide is one signed sinusoid along any fixed axis; projected on axes that follow a noisy mean flow
from place to place, its amplitude changes with the place, which a uniform tide term cannot fit. CASEs as in
bench/bench_time_judge.py.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from forcemap.host.workbench import flow_axis, survey_fits
from forcemap.host.workbench.errors import WorkbenchError

from bench.bench_time_judge import crossline


def survey_axis_frame(me, mn, survey, X: dict, mean: tuple | None = None):  # type: ignore[no-untyped-def]
    """`flow_axis.axis_frame` with the survey's overall axis at every place of `X`."""
    tau_mean, tau_cov = flow_axis.cycle_stats(me, mn, survey)
    rows = flow_axis.survey_inputs_cached(survey)
    ref = flow_axis.reference(
        flow_axis.mean_flow(me, rows), flow_axis.mean_flow(mn, rows), tau_mean, tau_cov
    )
    n = len(next(iter(X.values())))
    return np.full(n, ref[0]), np.full(n, ref[1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("case")
    p.add_argument("--terms", nargs="+", default=["", "tide"])
    p.add_argument("--target", default="current_speed")
    p.add_argument("--cases-dir", type=Path, default=Path("/tmp/forcemap-cases"))
    a = p.parse_args()
    try:
        # `crossline` loads the survey anew on each call, so each run builds its own frames
        print("axis at each place:", flush=True)
        crossline(a.case, a.cases_dir, a.target, a.terms)
        survey_fits.axis_frame = survey_axis_frame
        print("one axis for the survey:", flush=True)
        crossline(a.case, a.cases_dir, a.target, a.terms)
    except (WorkbenchError, FileNotFoundError, KeyError) as e:
        print(f"bench_tide_frame: {e}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
