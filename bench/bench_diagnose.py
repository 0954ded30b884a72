"""Benchmark: `diagnose` on every hidden effect of the simulator, and on surveys with none.

Each survey is made by `forcemap.sim_devices.offline.make_survey` (river, lawnmower, 20 minutes, the real
firmware and the daemon's pipeline, exported to a samples table), as in tests/test_workbench_effects.py.
For each it prints the covariate ranked first, its blocked-CV gain and p-value, whether the diagnosis
reports a missing effect, and the time `diagnose` took as a ratio to the named baseline: fitting the
paper's baseline model alone on the same survey, in the same process.

    python bench/bench_diagnose.py [--seeds 1,2] [--duration 1200] [--effects gusts,none]
                                   [--out /tmp/forcemap-bench-diagnose]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from forcemap.host.workbench.diagnose import DIAGNOSE_MAX_BASIS, diagnose
from forcemap.host.workbench.table import load_survey
from forcemap.host.workbench.targets import SurveyModel
from forcemap.sim_devices.offline import make_survey

CASES = [
    ("none", "current_speed", "none"),
    ("none", "wind_speed", "none"),
    ("depth_current", "current_speed", "depth"),
    ("dam_release", "current_speed", "t"),
    ("gusts", "wind_speed", "t"),
    ("bank_shelter", "wind_speed", "wind_dir"),
    ("wheel_misalignment", "current_speed", "heading*"),
    ("anemometer_upwash", "wind_speed", "stw"),
    ("compass_deviation", "current_dir", "heading*"),
    ("clock_offset", "wind_dir", "clock_offset"),
]


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--duration", type=float, default=1200.0)
    ap.add_argument(
        "--effects", default="", help="only these effects (comma-separated; default all)"
    )
    ap.add_argument("--out", default="/tmp/forcemap-bench-diagnose")
    args = ap.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    print(
        "expected: heading* = heading, heading_rel_current or heading_rel_wind (one covariate on a"
    )
    print("lawnmower); none = no missing effect reported\n")
    head = (
        f"{'effect':<19} {'target':<14} {'seed':>4} {'expected':<10} {'ranked first':<20} "
        f"{'gain':>6} {'p':>8} {'found':>5} {'baseline fit':>12} {'diagnose':>9} {'ratio':>6}"
    )
    print(head)
    print("-" * len(head))
    only = {e for e in args.effects.split(",") if e}
    for effect, target, expected in CASES:
        if only and effect not in only:
            continue
        for seed in seeds:
            out = Path(args.out) / f"{effect}-{seed}"
            table = out / "samples.csv"
            if not table.exists():
                effects = [] if effect == "none" else [effect]
                table = make_survey("river", effects, seed, args.duration, out)
            survey = load_survey(table)
            t0 = time.perf_counter()
            SurveyModel(survey, target, max_basis=DIAGNOSE_MAX_BASIS).fit()
            t_base = time.perf_counter() - t0
            survey = load_survey(table)  # a fresh cache, so diagnose pays for its own baseline
            t0 = time.perf_counter()
            d = diagnose(survey, target, progress=False)
            t_diag = time.perf_counter() - t0
            best = d.candidates[0]
            print(
                f"{effect:<19} {target:<14} {seed:>4} {expected:<10} {best.covariate:<20} "
                f"{best.improvement:>+6.0%} {best.p_value:>8.1e} {'yes' if d.missing_effect_found else 'no':>5} "
                f"{t_base:>11.1f}s {t_diag:>8.1f}s {t_diag / t_base:>5.1f}x",
                flush=True,
            )


if __name__ == "__main__":
    main()
