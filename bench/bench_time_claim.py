"""Time found on blocks and checked at the revisits (bench/RESULTS.md, "A short survey without an effect,
where the blocks overrule the revisits").

    python -m bench.bench_time_claim [-o /tmp/forcemap-bench-time-claim]

For simulated river surveys (`make_survey`, made once into -o), the first round of `diagnose` on
`current_speed`: the revisits' forms (p), the blocks' gain and p-value of a GP in t, whether `t` is
credited, and how far the pipeline's measured current speed is from the simulator's truth (the largest
1-minute mean of measured minus true: a calibration settling in the first minutes would show there).
Beside them, a check tried and not kept in diagnose: the change the blocks' model fitted (the model
plus `gp(t, matern32)`, every input but time held at the first row) makes differences at the revisit
pairs; the RMS of those, the RMS of the pairs' own differences (the baseline's residuals, the time
judge's nuisance taken out of both), the slope of the second on the first, and its one-sided p-value
against the judge's exchanges of whole stretches' times.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from forcemap.host.workbench.diagnose.rounds import diagnose
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms.spec import BASELINE
from forcemap.host.workbench.timejudge import forms as tf
from forcemap.host.workbench.timejudge.candidate import revisits_of
from forcemap.sim_devices.offline import make_survey

# (effects, seed, duration s): surveys without an effect, and weak or combined releases
SURVEYS = [
    ((), 2, 900.0),
    (("dam_release",), 1, 900.0),
    (("dam_release",), 2, 900.0),
    ((), 1, 1200.0),
    ((), 2, 1200.0),
    (("dam_release:increase=0.035",), 1, 1200.0),
    (("dam_release:increase=0.035",), 4, 1200.0),
    (("depth_current", "dam_release"), 2, 1200.0),
]


def claim_check(table: Path, permutations: int = 999) -> str:
    """The blocks' change in time at the baseline's revisit pairs, against their own differences."""
    survey = load_survey(table)
    sm = SurveyModel(survey, "current_speed", None, max_basis=600).fit()
    found = revisits_of(sm)
    if found is None:
        return "no revisits"
    rows, rp = found.rows, found.rp
    ext = SurveyModel(survey, "current_speed", [*BASELINE, "gp(t, matern32)"], max_basis=600).fit()
    held = {k: v if k == "t" else np.repeat(v[:1], len(v), axis=0) for k, v in ext.X.items()}
    change = ext.primary.predict(held)[rows]
    resid = (sm.y_primary - sm.primary.predict(sm.X))[rows]
    heading = sm.survey.columns["heading"][rows]
    proj = tf.Projector(tf.nuisance(rp, sm.survey.xy[rows], heading))
    d = proj(tf.clipped((resid[rp.pairs[:, 1]] - resid[rp.pairs[:, 0]])[:, None]))[:, 0]

    def claimed(order=None) -> np.ndarray:
        ta, tb = rp.times(order)
        return np.interp(tb, rp.t, change) - np.interp(ta, rp.t, change)

    def z(c: np.ndarray) -> float:
        c = proj(c[:, None])[:, 0]
        return float(d @ c) / max(float(np.sqrt(c @ c)), 1e-300)

    raw = claimed()
    c = proj(raw[:, None])[:, 0]
    rng = np.random.default_rng(0)
    null = np.array([z(claimed(rng.permutation(rp.n_stretches))) for _ in range(permutations)])
    p = (1 + (null >= z(raw)).sum()) / (1 + permutations)
    return (
        f"check {np.sqrt(np.mean(raw**2)):.3f} vs {np.sqrt(np.mean(d**2)):.3f} RMS, "
        f"slope {float(d @ c) / float(c @ c):.2f}, p {p:.3f}"
    )


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
    forms_p = "-" if t.time is None else f"{t.time.p_value:.3f}"
    cells = [
        f"forms p {forms_p}",
        f"blocks {t.blocked_gain:+.0%} p {t.blocked_p:.1e}",
        claim_check(table),
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
