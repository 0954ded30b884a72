"""The heading and time confounded at the revisits of a race course (bench/RESULTS.md, "The heading and time
confounded on a race course").

    python -m bench.bench_heading_confound CASE [CASE ...] [--period S] [--permutations 999]

For the first round's residuals of `current_speed` (the inputs `time_candidate.time_verdict` gives the
judge), it prints the drift's share of the revisit differences with the heading's harmonics taken out (as
the judge does) and without them, the same at `--period` with the share of the periodic columns' energy
the harmonics leave, and the judge's verdict (with the kinds of form it cannot tell from its best), also
once the heading's effect, estimated where the heading changes fast (tacks, turns: the rows' values and
harmonics less their course in time, hat functions two stretches apart), is subtracted instead. CASEs as
in bench/bench_time_judge.py.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from forcemap.host.workbench.diagnose.catalogue import kind_named
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.timejudge import candidate as time_candidate
from forcemap.host.workbench.timejudge import forms as tf
from forcemap.host.workbench.timejudge.judge import judge_time
from scipy.linalg import solveh_banded

from bench.bench_time_judge import table_of


def judged_rows(case: str, cases: Path, target: str):  # type: ignore[no-untyped-def]
    """What time_verdict judges: the kept rows' values, times, positions and headings, and their pairs."""
    sm = SurveyModel(load_survey(table_of(case, cases)), target, None, max_basis=600).fit()
    found = time_candidate.revisits_of(sm)
    if found is None:
        raise WorkbenchError(f"{case}: the track comes back too little to judge time")
    rows, rp, _, values = found
    s = sm.survey
    heading = s.columns.get("heading")
    return values[rows], s.trel[rows], s.xy[rows], None if heading is None else heading[rows], rp


def harmonics(heading: np.ndarray) -> np.ndarray:
    h = np.radians(heading)
    return np.column_stack([f(k * h) for k in (1, 2) for f in (np.cos, np.sin)])


def fast_heading_effect(values, t, heading, spacing_s: float) -> np.ndarray:
    """The heading's effect on each row, estimated from what changes faster than `spacing_s`: the values and
    the harmonics less their course in time (hat functions, a banded least squares), regressed."""
    Y = np.column_stack([values, harmonics(heading)])
    u = (t - t.min()) / spacing_s
    k = np.minimum(np.floor(u).astype(int), max(int(np.ceil(u.max())) - 1, 0))
    wa, wb = 1.0 - (u - k), u - k
    K = k.max() + 2
    diag = np.bincount(k, wa * wa, K) + np.bincount(k + 1, wb * wb, K)
    ab = np.vstack([np.r_[0.0, np.bincount(k, wa * wb, K)[:-1]], diag + 1e-9 * diag.max()])
    rhs = np.zeros((K, Y.shape[1]))
    np.add.at(rhs, k, wa[:, None] * Y)
    np.add.at(rhs, k + 1, wb[:, None] * Y)
    alpha = solveh_banded(ab, rhs)
    left = Y - (wa[:, None] * alpha[k] + wb[:, None] * alpha[k + 1])
    n = values.shape[1]
    gamma = np.linalg.lstsq(left[:, n:], left[:, :n], rcond=None)[0]
    return harmonics(heading) @ gamma


def report(case: str, cases: Path, target: str, period_s: float, permutations: int) -> None:
    values, t, xy, heading, rp = judged_rows(case, cases, target)
    a, b = rp.pairs[:, 0], rp.pairs[:, 1]
    ta, tb = rp.times()
    N = tf.nuisance(rp, xy, heading)
    d = tf.clipped(values[b] - values[a])
    cells = []
    for label, P in (
        ("with the heading's harmonics", tf.Projector(N)),
        ("without", tf.Projector(N[:, :2])),
    ):
        drift = tf.share_of(P(d), tf.drift_columns(ta, tb, float(np.ptp(rp.t)), P))
        C, S = tf.periodic_columns(ta, tb, np.array([2 * np.pi / period_s]), P)
        cells.append(
            f"{label}: drift {drift:.3f}, {period_s:.0f} s {tf.pair_shares(P(d), C, S)[0]:.3f}"
        )
    C0, S0 = tf.periodic_columns(ta, tb, np.array([2 * np.pi / period_s]), tf.Projector(None))
    C1, S1 = tf.periodic_columns(ta, tb, np.array([2 * np.pi / period_s]), tf.Projector(N))
    kept = ((C1**2).sum() + (S1**2).sum()) / ((C0**2).sum() + (S0**2).sum())
    cells.append(f"energy the harmonics leave at {period_s:.0f} s {kept:.2f}")
    base = judge_time(values[b] - values[a], rp, xy, heading, permutations=permutations)
    vv = values - fast_heading_effect(values, t, heading, 2.0 * rp.stretch_s)
    sub = judge_time(vv[b] - vv[a], rp, xy, None, permutations=permutations)
    for label, v in (("judge", base), ("turns' estimate subtracted", sub)):
        period = "" if v.best.period_s is None else f" {v.best.period_s:.0f} s"
        others = " or ".join(kind_named(v, k) for k in v.indistinct)
        told = f" (not told from {others})" if others else ""
        cells.append(
            f"{label}: p {v.p_value:.4f}, share {v.share:.3f}, {v.best.name}{period}{told}"
        )
    print(f"{case} {target} ({len(rp.pairs)} pairs) | " + " | ".join(cells), flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("cases", nargs="+", metavar="CASE")
    p.add_argument("--target", default="current_speed")
    p.add_argument("--period", type=float, default=4440.0, help="a period to look at (s)")
    p.add_argument("--permutations", type=int, default=999)
    p.add_argument("--cases-dir", type=Path, default=Path("/tmp/forcemap-cases"))
    a = p.parse_args()
    a.cases_dir.mkdir(parents=True, exist_ok=True)
    try:
        for case in a.cases:
            report(case, a.cases_dir, a.target, a.period, a.permutations)
    except (WorkbenchError, FileNotFoundError, KeyError) as e:
        print(f"bench_heading_confound: {e}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
