"""Benchmark: `diagnose` on every hidden effect of the simulator, and on surveys with none.

Each survey is made by `forcemap.sim_devices.offline.make_survey` (river, lawnmower, 20 minutes, the real
firmware and the daemon's pipeline, exported to a samples table), as in tests/test_workbench_effects.py.
For each it prints the covariate ranked first, its blocked-CV gain, the best of its nulls (time-shifted
copies), whether it is identifiable, its p-value, whether the diagnosis reports a missing effect, and the
cost: fitting the paper's baseline model alone on the same survey (the named baseline, same process), the
first round of `diagnose`, and that round's calibration (null and identifiability) against its candidate
evaluations, which are what the diagnosis cost before the calibration. The last case runs every round
(two hidden effects; --rounds, default 3) on a 20-minute survey of about 4,800 samples.

    python bench/bench_diagnose.py [--seeds 1,2] [--duration 1200] [--phenomena gusts,none]
                                   [-o /tmp/forcemap-bench-diagnose] [--rounds 3]

(--effects and --out, the spellings of earlier runs in bench/RESULTS.md, still work.)
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from forcemap.host.workbench.diagnose.rounds import DIAGNOSE_MAX_BASIS, diagnose
from forcemap.host.workbench.engine.model import small_blas
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.sim_devices.offline import make_survey

CASES = [
    ("none", "current_speed", "none"),
    ("none", "wind_speed", "none"),
    ("depth_current", "current_speed", "depth"),
    ("dam_release", "current_speed", "t"),
    ("dam_release:increase=0.06", "current_speed", "t"),
    ("gusts", "wind_speed", "t"),
    ("bank_shelter", "wind_speed", "wind_dir"),
    ("wheel_misalignment", "current_speed", "heading*"),
    ("anemometer_upwash", "wind_speed", "stw"),
    ("compass_deviation", "current_dir", "heading*"),
    ("clock_offset", "wind_dir", "clock_offset"),
    ("depth_current,dam_release", "current_speed", "depth+t"),
]


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--duration", type=float, default=1200.0)
    ap.add_argument(
        "--phenomena",
        "--effects",
        dest="effects",
        default="",
        help="only these cases (comma-separated; two effects at once as depth_current+dam_release; default all)",
    )
    ap.add_argument("-o", "--output", "--out", dest="out", default="/tmp/forcemap-bench-diagnose")
    ap.add_argument("--rounds", type=int, default=3, help="rounds for the two-effect case")
    args = ap.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    print(
        "expected: heading* = heading, heading_rel_current or heading_rel_wind (one covariate on a"
    )
    print("lawnmower); none = no missing effect reported; increase=0.06 is the weak effect\n")
    head = (
        f"{'effect':<19} {'target':<14} {'seed':>4} {'expected':<10} {'ranked first':<20} "
        f"{'gain':>6} {'null':>6} {'ident':>5} {'p':>8} {'found':>5} {'baseline fit':>12} {'diagnose':>9} "
        f"{'ratio':>6} {'calibration':>11}"
    )
    print(head)
    print("-" * len(head))
    only = {e for e in args.effects.split(",") if e}
    known = {effect.replace(",", "+") for effect, _, _ in CASES}
    if only - known:
        ap.error(
            f"unknown case {', '.join(sorted(only - known))}; one of {', '.join(sorted(known))}"
        )
    for effect, target, expected in CASES:
        if only and effect.replace(",", "+") not in only:
            continue
        for seed in seeds:
            out = Path(args.out) / f"{effect.replace(',', '+')}-{seed}"
            table = out / "samples.csv"
            if not table.exists():
                effects = [] if effect == "none" else effect.split(",")
                table = make_survey("river", effects, seed, args.duration, out)
            survey = load_survey(table)
            t0 = time.perf_counter()
            SurveyModel(survey, target, max_basis=DIAGNOSE_MAX_BASIS).fit()
            t_base = time.perf_counter() - t0
            survey = load_survey(table)  # a fresh cache, so diagnose pays for its own baseline
            rounds = args.rounds if "+" in expected else 1
            t0 = time.perf_counter()
            with small_blas():
                d = diagnose(survey, target, rounds=rounds, progress=False)
            t_diag = time.perf_counter() - t0
            best = d.candidates[0]
            sec = d.first.seconds
            calib = (sec["null"] + sec["identifiability"]) / sec["candidates"]
            null = f"{max(best.null_gains):+6.0%}" if best.null_gains else f"{'':>6}"
            ident = {True: "yes", False: "no", None: ""}[best.identifiable]
            print(
                f"{effect:<19} {target:<14} {seed:>4} {expected:<10} {best.covariate:<20} "
                f"{best.improvement:>+6.0%} {null} {ident:>5} {best.p_value:>8.1e} "
                f"{'yes' if d.missing_effect_found else 'no':>5} "
                f"{t_base:>11.1f}s {t_diag:>8.1f}s {t_diag / t_base:>5.1f}x {calib:>10.2f}x",
                flush=True,
            )
            if len(d.rounds) > 1:
                print(f"    {len(d.rounds)} rounds on {survey.n:,} samples in {t_diag:.1f} s")
                for step in d.steps():
                    print(f"    {step}")


if __name__ == "__main__":
    main()
