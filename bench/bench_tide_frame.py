"""A tide on a speed target: the flow frame's axis at each place, one axis for the whole survey, and the one
forcemap chooses (bench/RESULTS.md, "A tide on a speed target and its frame").

    python -m bench.bench_tide_frame CASE [CASE ...] [--terms "" tide] [--target current_speed] [--chosen]

`fit`'s crossline RMSE (each time stretch held out, scored where the boat comes back) and blocked-CV RMSE
with the baseline plus each set of terms, three times: in the frame forcemap chooses when the terms hold a
tide or a seiche (host/workbench/targets/axis_choice.py: the held-out vector's error decides), then with each frame
forced (the choice's numbers are still printed, its verdict replaced); with `--chosen`, only the first. A uniform tide is one signed
sinusoid along any fixed axis; projected on axes that follow a noisy mean flow from place to place, its
amplitude changes with the place, which a uniform tide term cannot fit. CASEs as in bench/bench_time_judge.py.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.targets import survey_fits
from forcemap.host.workbench.targets.axis_choice import choose_axis

from bench.bench_time_judge import crossline


def forced(one_axis: bool):  # type: ignore[no-untyped-def]
    """`choose_axis` with its verdict replaced by `one_axis`."""

    def choose(fits, vt, time_terms):  # type: ignore[no-untyped-def]
        return dataclasses.replace(choose_axis(fits, vt, time_terms), one_axis=one_axis)

    return choose


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("case", nargs="+")
    p.add_argument("--terms", nargs="+", default=["", "tide"])
    p.add_argument("--target", default="current_speed")
    p.add_argument("--chosen", action="store_true", help="only the frame forcemap chooses")
    p.add_argument("--cases-dir", type=Path, default=Path("/tmp/forcemap-cases"))
    a = p.parse_args()
    a.cases_dir.mkdir(parents=True, exist_ok=True)
    for case in a.case:
        try:
            frames(case, a.cases_dir, a.target, a.terms, a.chosen)
        except (WorkbenchError, FileNotFoundError, KeyError) as e:
            print(f"bench_tide_frame: {case}: {e}", file=sys.stderr)
            raise SystemExit(2) from None


def frames(case: str, cases: Path, target: str, terms: list[str], chosen_only: bool) -> None:
    """The crossline and blocked CV in the frame forcemap chooses, then (unless `chosen_only`) in each."""
    # `crossline` loads the survey anew on each call, so each run builds (and chooses) its own frames
    survey_fits.choose_axis = choose_axis
    print("as forcemap chooses:", flush=True)
    crossline(case, cases, target, terms)
    if chosen_only:
        return
    for one_axis, words in ((False, "the axis at each place"), (True, "one axis for the survey")):
        survey_fits.choose_axis = forced(one_axis)
        print(f"{words}:", flush=True)
        crossline(case, cases, target, [t for t in terms if t])


if __name__ == "__main__":
    main()
