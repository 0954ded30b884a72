"""Time found on blocks and checked at the revisits (bench/RESULTS.md, "A short survey without an effect,
where the blocks overrule the revisits").

    python -m bench.bench_time_claim [-o /tmp/forcemap-bench-time-claim]

For simulated river surveys (`make_survey`, made once into -o), the first round of `diagnose` on
`current_speed`: the revisits' forms (p), the blocks' gain and p-value of a GP in t, and the check of
the blocks' change at the revisit pairs (`time_judge.check_claim`: the RMS it would make them differ by,
their own RMS, the slope they follow it with, its p-value), whether `t` is credited, and how far the
pipeline's measured current speed is from the simulator's truth (the largest 1-minute mean of measured
minus true: a calibration settling in the first minutes would show there).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from forcemap.host.workbench.diagnose.evaluate import Evaluator
from forcemap.host.workbench.diagnose.rounds import diagnose
from forcemap.host.workbench.spec import BASELINE
from forcemap.host.workbench.table import load_survey
from forcemap.sim_devices.offline import make_survey

# (effects, seed, duration s): surveys without an effect, and weak or combined releases
SURVEYS = [
    ((), 2, 900.0),
    ((), 1, 1200.0),
    ((), 2, 1200.0),
    (("dam_release:increase=0.035",), 1, 1200.0),
    (("dam_release:increase=0.035",), 4, 1200.0),
    (("depth_current", "dam_release"), 2, 1200.0),
]


def measurement_error(table: Path) -> float:
    """The largest |1-minute mean| of the measured current speed less the truth at the same times."""
    m = pd.read_csv(table, usecols=["t", "current_speed"])
    truth = pd.read_csv(table.parent / "truth" / "samples.csv", usecols=["t", "current_speed"])
    err = m["current_speed"] - np.interp(m["t"], truth["t"], truth["current_speed"])
    minute = ((m["t"] - m["t"].iloc[0]) // 60).astype(int)
    return float(err.groupby(minute).mean().abs().max())


def report(table: Path, label: str) -> None:
    """One survey's line."""
    survey = load_survey(table)
    d = diagnose(survey, "current_speed", rounds=1, progress=False)
    t = next(c for c in d.candidates if c.covariate == "t")
    ev = Evaluator(load_survey(table), "current_speed", list(BASELINE), 5, 0)
    ev.blocks_time = (ev.extended("t"), ev.inputs("t"))
    check = ev.time_claim()
    forms_p = "-" if t.time is None else f"{t.time.p_value:.3f}"
    cells = [
        f"forms p {forms_p}",
        f"blocks {t.blocked_gain:+.0%} p {t.blocked_p:.1e}",
        "no revisits"
        if check is None
        else f"check {check.rms_claimed:.3f} vs {check.rms_difference:.3f} RMS, slope {check.slope:.2f}, "
        f"p {check.p_value:.3f}",
        f"t credited: {'yes' if t.significant else 'no'}",
        f"first: {d.candidates[0].covariate if d.missing_effect_found else 'nothing'}",
        f"measured - truth <= {measurement_error(table):.3f} m/s (1-min means)",
    ]
    print(f"{label:<40} " + " | ".join(cells), flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--out", type=Path, default=Path("/tmp/forcemap-bench-time-claim"))
    a = p.parse_args()
    for effects, seed, duration in SURVEYS:
        label = f"{'+'.join(effects) or 'none'} seed {seed} {duration / 60:.0f} min"
        out = a.out / f"{'+'.join(effects) or 'none'}-{seed}-{duration:.0f}"
        table = out / "samples.csv"
        if not table.exists():
            table = make_survey("river", list(effects), seed, duration, out)
        report(table, label)


if __name__ == "__main__":
    main()
