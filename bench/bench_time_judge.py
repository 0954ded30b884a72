"""Time judged where the boat comes back: the revisits' p-value per survey and radius, and the crossline RMSE
of the terms a verdict may advise (bench/RESULTS.md, "Time judged where the boat comes back").

    python -m bench.bench_time_judge radius CASE [CASE ...] [--shares 0.2,0.5]
    python -m bench.bench_time_judge crossline CASE --terms "" "tide" "gp(t, matern32)" [--target T]
    python -m bench.bench_time_judge cost CASE [--target T] [--permutations 200] [--diagnose-only]
    python -m bench.bench_time_judge seeds CASE [--target T] [--seeds 4] [--threshold 0.0021]

`seeds` prints the verdict's p-value on the baseline model's revisits for each seed of the exchanges: from
999 of them, and as diagnose takes it against `--threshold` (0.05 over 24 candidates by default: a
thousand more at a time, up to 9,999, while the p-value is too close to the threshold to decide,
`time_judge.undecided`).

`cost` prints the CPU of `diagnose` on the case (and its first round's verdict on `t`, and its `closest:` line
when that round credits nothing), and of one permutation of the revisit judge's null on the
baseline model's revisit pairs: from products over the stretches (`PermutedTimes.null`, what diagnose runs)
and from the pairs' columns formed in full (`FormLadder.shares`), with the largest difference between them.

A CASE is an injected real case of tests/real_cases.py (`geneva_seiche`, `lake_drift`, `fjord_tide`,
`fjord_seiche`, `fjord_level`, `plaka_level`), a real log's path under the real data
(`nmea/irene/irene_2014-06-27_geneva.nmea`), or a samples table (a simulated survey's `samples.csv`). Cases
are built once into --cases (default /tmp/forcemap-cases) and reused.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.fits.fit import fit_target
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms.spec import BASELINE
from forcemap.host.workbench.timejudge.candidate import time_verdict
from forcemap.host.workbench.timejudge.revisits import MIN_RADIUS_M, map_lengthscale


def table_of(case: str, cases: Path) -> Path:
    """The samples table of `case`: a table given as such, or a real case built once into `cases`."""
    if case.endswith((".csv", ".parquet")):
        return Path(case)
    from tests.real_cases import Cases

    return Cases(cases)(case).csv


def radius(case: str, cases: Path, target: str, shares: list[float]) -> None:
    """The revisits' verdict on the baseline model at each radius (a share of the map's length scale)."""
    sm = SurveyModel(load_survey(table_of(case, cases)), target, None, max_basis=600).fit()
    ell = map_lengthscale(sm)
    cells = []
    for share in shares:
        r = max(share * ell, MIN_RADIUS_M)
        c0 = time.process_time()
        found = time_verdict(sm, r)
        if found is None:
            cells.append(f"R {r:.0f} m: too few revisits")
            continue
        v = found[0]
        cells.append(
            f"R {r:.0f} m: {v.crossings} crossings, p {v.p_value:.3f}, {v.best.name} "
            f"{'' if v.best.period_s is None else f'{v.best.period_s / 60:.0f} min'}, cv share "
            f"{v.share:.2f} ({time.process_time() - c0:.0f} s CPU)"
        )
    print(f"{case} {target} (length scale {ell:.0f} m) | " + " | ".join(cells), flush=True)


def crossline(case: str, cases: Path, target: str, terms: list[str]) -> None:
    """`fit`'s crossline RMSE with the baseline plus each set of terms (`;` between terms of one set), and a
    depth level's check where `fit` makes one."""
    survey = load_survey(table_of(case, cases))
    for extra in terms:
        ts = [*BASELINE, *[t for t in extra.split(";") if t]]
        r = fit_target(survey, target, ts, progress=False)
        xl = "none" if r.crossline is None else f"{r.crossline['crossline_rmse']:.4f}"
        axis = "" if r.model.axis is None else f"; {r.model.axis.line()}"
        if r.model.axis is not None and r.model.axis.one_axis:
            toward = np.degrees(np.arctan2(r.model.ue[0], r.model.un[0])) % 360.0
            axis += f", along {toward:05.1f} deg"
        if (lv := r.level) is not None:  # a depth level checked held out (level_check)
            axis += f"; level {lv.verdict}: mean squares differ by {lv.difference:.4g}"
            axis += f", sd {lv.sd_difference:.4g}"
            axis += f", range {lv.range_m:.4g} m"
            axis += level_against_truth(case, cases, survey, r.model)
        print(
            f"{case} {target} + [{extra}]: crossline RMSE {xl}, blocked CV {r.cv.rmse:.4f}{axis}",
            flush=True,
        )


def level_against_truth(case: str, cases: Path, survey, sm) -> str:  # type: ignore[no-untyped-def]
    """An injected case's fitted level against its truth's (`inject_verify.level_match`)."""
    import pandas as pd

    from bench.inject_verify import level_match

    if case.endswith((".csv", ".parquet")):
        return ""
    from tests.real_cases import Cases

    truth_file = Cases(cases)(case).truth
    if truth_file is None:
        return ""
    return f"; against the truth: {level_match(sm, survey, pd.read_csv(truth_file)).line()}"


def cost(case: str, cases: Path, target: str, permutations: int, diagnose_only: bool) -> None:
    """CPU of `diagnose` on the case, and of one permutation of the judge's null, both ways."""
    from forcemap.host.workbench.diagnose.rounds import diagnose
    from forcemap.host.workbench.timejudge import candidate as time_candidate

    survey = load_survey(table_of(case, cases))
    c0 = time.process_time()
    d = diagnose(survey, target, progress=False)
    line = f"{case} {target}: {survey.n} rows, diagnose {time.process_time() - c0:.1f} s CPU"
    line += time_finding(d)
    if near := d.rounds[0].closest_line():  # nothing credited: the candidate of the smallest p-value
        line += "\n" + near.strip()
    if diagnose_only:
        print(line, flush=True)
        return
    judged = []
    real = time_candidate.judge_time
    time_candidate.judge_time = lambda *a, **k: judged.append(a) or real(*a, **k)
    try:
        time_verdict(SurveyModel(survey, target, None, max_basis=600).fit())
    finally:
        time_candidate.judge_time = real
    if not judged:
        print(f"{line}; the track comes back too little to judge time", flush=True)
        return
    print(f"{line}; {null_cost(*judged[0], permutations)}", flush=True)


def seeds(case: str, cases: Path, target: str, n: int, threshold: float) -> None:
    """The verdict's p-value for seeds 0 .. n-1: from PERMUTATIONS exchanges, and resolved against
    `threshold` (`judge_time`'s `threshold`)."""
    from forcemap.host.workbench.timejudge.candidate import judged_pairs, revisits_of
    from forcemap.host.workbench.timejudge.judge import judge_time

    sm = SurveyModel(load_survey(table_of(case, cases)), target, None, max_basis=600).fit()
    found = revisits_of(sm)
    if found is None:
        print(f"{case} {target}: the track comes back too little", flush=True)
        return
    args = judged_pairs(sm, found)
    cells = []
    for seed in range(n):
        first = judge_time(*args, seed=seed)
        c0 = time.process_time()
        resolved = judge_time(*args, seed=seed, threshold=threshold)
        cells.append(
            f"seed {seed}: p {first.p_value:.4f} ({first.permutations}), {resolved.p_value:.4f} "
            f"({resolved.permutations}, {time.process_time() - c0:.1f} s CPU)"
        )
    print(f"{case} {target} against {threshold:.4f} | " + " | ".join(cells), flush=True)


def time_finding(d) -> str:
    """The first round's verdict on `t` at the revisits, if it was judged there: form, period, advice, and
    the advised term's blocked-CV error beside the next round's model's (the same model, refitted)."""
    t = next((c for c in d.rounds[0].candidates if c.covariate == "t"), None)
    v = None if t is None else t.time
    if v is None:
        return ""
    out = f"; t: p {v.p_value:.3f}, {v.best.name}"
    if v.best.period_s is not None:
        sd = "" if v.period_sd_s is None else f" +- {v.period_sd_s:.0f}"
        out += f" {v.best.period_s:.0f}{sd} s"
    if v.fitted_period_s is not None:
        out += f", the fit's {v.fitted_period_s:.0f} +- {v.fitted_period_sd_s:.0f} s"
    if not t.significant:
        return out
    out += f", advised {t.term} (blocked CV {d.rounds[0].cv_rmse:.4f} -> {t.cv_rmse:.4f}, {t.blocked_gain:+.0%}"
    if len(d.rounds) > 1 and d.rounds[0].added is t:
        out += f"; the next round's model {d.rounds[1].cv_rmse:.4f}"
    return out + ")"


def null_cost(d, rp, xy, heading, permutations: int) -> str:
    """One permutation's CPU (ms) from products over the stretches and from the columns formed in full."""
    from forcemap.host.workbench.timejudge import forms as tf
    proj = tf.Projector(tf.nuisance(rp, xy, heading))
    d = proj(tf.clipped(np.asarray(d, float).reshape(len(rp.pairs), -1)))
    ladder = tf.FormLadder(float(np.ptp(rp.t)), rp.stretch_s)
    rng = np.random.default_rng(0)
    orders = np.array([rng.permutation(rp.n_stretches) for _ in range(permutations)])
    c0 = time.process_time()
    fast = tf.PermutedTimes(rp, ladder, proj).null(d, orders)
    c1 = time.process_time()
    full = np.array([ladder.shares(d, *rp.times(o), proj) for o in orders])
    c2 = time.process_time()
    diff = float(np.max(np.abs(fast - full)) / max(float(np.abs(full).max()), 1e-300))
    return (
        f"null on {len(rp.pairs)} pairs, {rp.n_stretches} stretches: {1e3 * (c1 - c0) / permutations:.2f} ms "
        f"a permutation over the stretches, {1e3 * (c2 - c1) / permutations:.1f} ms with the columns in "
        f"full, largest difference {diff:.1e} of the largest share"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("what", choices=("radius", "crossline", "cost", "seeds"))
    p.add_argument("cases", nargs="+", metavar="CASE")
    p.add_argument("--target", default="current_speed")
    p.add_argument("--shares", default="0.2,0.5", help="radii as shares of the map's length scale")
    p.add_argument("--terms", nargs="+", default=["", "tide", "gp(t, matern32)"])
    p.add_argument("--permutations", type=int, default=200, help="cost: permutations timed each way")
    p.add_argument("--diagnose-only", action="store_true", help="cost: only diagnose's CPU")
    p.add_argument("--seeds", type=int, default=4, help="seeds: how many seeds of the exchanges")
    p.add_argument("--threshold", type=float, default=0.05 / 24, help="seeds: diagnose's threshold")
    p.add_argument("--cases-dir", type=Path, default=Path("/tmp/forcemap-cases"))
    a = p.parse_args()
    a.cases_dir.mkdir(parents=True, exist_ok=True)
    try:
        run(a)
    except (WorkbenchError, FileNotFoundError, KeyError) as e:
        print(f"bench_time_judge: {e}", file=sys.stderr)
        raise SystemExit(2) from None


def run(a: argparse.Namespace) -> None:
    """Each case in turn, as the command line asks."""
    for case in a.cases:
        if a.what == "radius":
            radius(case, a.cases_dir, a.target, [float(x) for x in a.shares.split(",")])
        elif a.what == "seeds":
            seeds(case, a.cases_dir, a.target, a.seeds, a.threshold)
        elif a.what == "cost":
            cost(case, a.cases_dir, a.target, a.permutations, a.diagnose_only)
        else:
            crossline(case, a.cases_dir, a.target, a.terms)


if __name__ == "__main__":
    main()
