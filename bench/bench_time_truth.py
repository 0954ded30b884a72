"""What the revisits can see of an injected current: the case's injected part scaled, and the time judge's
verdict on each (bench/RESULTS.md, "What the revisits see of an injected current").

    python -m bench.bench_time_truth CASE [CASE ...] [--gains 0,1,2,3]

A CASE is an injected case of tests/real_cases.py (`geneva_seiche`, `lake_drift`, `fjord_tide`,
`fjord_seiche`, `fjord_level`, `plaka_level`). Gain 1 is the case's table as built; gain g adds (g - 1)
times the injected current to its east and north columns and recomputes the speed and direction, or (g - 1)
times the injected level to its depth (the table level, not the NMEA: the pipeline keeps an injected current
with slopes 0.96-1.01 and a level with 1.001, bench/RESULTS.md "Known effects injected into real NMEA
logs"); gain 0 is the case with its injection taken out again. A current is judged on `current_speed` (its
east and north components), a level on `depth`.

Per gain, the baseline model's revisits (`time_candidate.revisits_of`), as diagnose judges them:
- the verdict (`judge_time`): p-value, form, period, and how many crossings the change it fits rests on
  (`time_judge.evidence`);
- the size of the change it fits and its sd (`TimeVerdict.change`: a drift's from the first pass the revisits
  compare to the last, a period's amplitude) beside the truth's change over the same span; for a drift that
  turns between them, its largest departure from its start (`TimeVerdict.departure`) beside the truth's;
- `kept`: the share of the injected current's sd the maps leave in their residuals (the same component models
  with their hyperparameters fixed, fitted to the injected current alone: the map is a linear smoother there);
- `truth explains`: the share of the revisit differences' sum of squares that the injected current's own
  differences (through the maps, the nuisance taken out) explain, with its fitted coefficient per component
  (1 where the revisits see it as it is; at gain 0 the truth of gain 1, which is not in the table);
- `through the maps`: the period whose columns, passed through the same maps before they are differenced,
  explain the most of the differences (Frisch-Waugh-Lovell with the map as a nuisance; the judge itself
  differences the bare columns);
- `oracle p`: the best any judge of these revisits could do, one that knew the injected part's shape in
  time (its amplitude per component free): the share its own bare differences explain, against the same
  exchanges of whole stretches' times the judge draws (999). At gain 0, the shape of gain 1 (a null).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.timejudge import forms as tf
from forcemap.host.workbench.timejudge.candidate import judged_pairs, revisits_of
from forcemap.host.workbench.timejudge.judge import judge_time

PERIODS_MIN = np.geomspace(20.0, 300.0, 40)


def scaled_table(case: str, cases: Path, gain: float) -> tuple[Path, pd.DataFrame]:
    """The case's table with its injected current times `gain`, and the truth."""
    from tests.real_cases import Cases

    built = Cases(cases)(case)
    if built.truth is None:
        raise WorkbenchError(f"{case}: not an injected case")
    truth = pd.read_csv(built.truth)
    out = cases / f"{case}.gain{gain:g}" / "log.csv"
    if not out.exists():
        df = pd.read_csv(built.csv)
        if is_level(truth):
            df["depth"] += (gain - 1.0) * np.interp(df.t, truth.t, truth.level)
        if "current_east" in df:  # a log without a heading has no current
            for c in ("east", "north"):
                df[f"current_{c}"] += (gain - 1.0) * np.interp(df.t, truth.t, truth[f"current_{c}"])
            df["current_speed"] = np.hypot(df.current_east, df.current_north)
            df["current_dir"] = np.degrees(np.arctan2(df.current_east, df.current_north)) % 360.0
        out.parent.mkdir(parents=True, exist_ok=True)
        df.to_csv(out.with_suffix(".tmp"), index=False)
        out.with_suffix(".tmp").rename(out)
    return out, truth


def is_level(truth: pd.DataFrame) -> bool:
    """Whether the case's injected part is a water level (soundings read deeper), not a current."""
    return bool(np.ptp(truth.level) > 0)


def component_models(sm: SurveyModel) -> list[SurveyModel]:
    """The judged components' models: a vector's east and north models with `sm`'s terms, or `sm`."""
    if sm.vector is None:
        return [sm]
    terms = [str(x) for x in sm.term_specs]
    return [
        SurveyModel(sm.survey, sm.vector.column(aspect), terms, max_basis=600).fit()
        for aspect in ("east", "north")
    ]


def components(sm: SurveyModel, truth: pd.DataFrame, t: np.ndarray):
    """The judged components' models (`component_models`) and the injected part on each at UNIX times `t`."""
    cols = ["level"] if sm.vector is None else ["current_east", "current_north"]
    return [(m, np.interp(t, truth.t, truth[c])) for m, c in zip(component_models(sm), cols, strict=True)]


def through_map(m: SurveyModel, Y: np.ndarray) -> np.ndarray:
    """Each column of Y less the map of `m` fitted to it with `m`'s hyperparameters (its residual)."""
    out = np.empty_like(Y)
    for j in range(Y.shape[1]):
        p = m.new_primary()
        p.set_params(init=np.asarray(m.primary.theta_), optimize=False)
        p.fit(m.X, Y[:, j])
        out[:, j] = Y[:, j] - p.predict(m.X)
    return out


def share_by_component(d: np.ndarray, cols: list[np.ndarray]) -> float:
    """Share of d's sum of squares explained by each component's own columns (least squares)."""
    ex = 0.0
    for k, A in enumerate(cols):
        w, *_ = np.linalg.lstsq(A, d[:, k], rcond=None)
        ex += float(((A @ w) ** 2).sum())
    return ex / float((d * d).sum())


def judge_gain(table: Path, truth: pd.DataFrame, gain: float, amplitude: str) -> str:
    """One gain's line: the verdict, what the maps keep of the truth, what the truth explains."""
    target = "depth" if is_level(truth) else "current_speed"
    sm = SurveyModel(load_survey(table), target, None, max_basis=600).fit()
    s = sm.survey
    found = revisits_of(sm)
    if found is None:
        return f"gain {gain:g}: the track comes back too little"
    d0, rp, xy, hd = judged_pairs(sm, found)
    v = found.rows[rp.pairs]
    ver = judge_time(d0, rp, xy, hd)
    proj = tf.Projector(tf.nuisance(rp, xy, hd))
    d = proj(tf.clipped(d0))
    u = s.trel / np.ptp(s.trel)
    F = np.column_stack(
        [f(2 * np.pi * s.trel / (60 * P)) for P in PERIODS_MIN for f in (np.cos, np.sin)]
    )
    kept, truth_cols, form_cols = [], [], []
    for m, T in components(sm, truth, s.trel + s.t0):
        T = T * (gain if gain > 0 else 1.0)
        R = through_map(m, np.column_stack([T, F, u, u * u]))
        kept.append(np.std(R[:, 0]) / max(np.std(T), 1e-12))
        diff = proj(R[v[:, 1]] - R[v[:, 0]])
        truth_cols.append(diff[:, :1])
        form_cols.append(diff[:, 1:])
    coef = [float(np.linalg.lstsq(c, d[:, k], rcond=None)[0][0]) for k, c in enumerate(truth_cols)]
    shares = [
        share_by_component(d, [c[:, 2 * i : 2 * i + 2] for c in form_cols])
        for i in range(len(PERIODS_MIN))
    ]
    drift = share_by_component(d, [c[:, -2:] for c in form_cols])
    best = int(np.argmax(shares))
    b = ver.best
    period = "" if b.period_s is None else f" {b.period_s / 60:.0f} min"
    step, away = truth_change(truth, s.t0 + np.array(ver.change_span_s), gain)
    turns = f"; departs up to {ver.departure:.3g} ± {ver.departure_sd:.2g}" if ver.departure else ""
    mapped = f"{PERIODS_MIN[best]:.0f} min ({shares[best]:.3f}; drift {drift:.3f})"
    oracle = oracle_p(d, rp, proj, truth, s.t0)
    return (
        f"gain {gain:g} ({amplitude}): {ver.crossings} crossings, p {ver.p_value:.3f}, {b.name}{period} "
        f"(resting on {ver.evidence_crossings:.1f} crossings, most at {ver.evidence_at_s[0] / 60:.0f} and "
        f"{ver.evidence_at_s[1] / 60:.0f} min; its change {ver.change:.3g} ± {ver.change_sd:.2g} from "
        f"{ver.change_span_s[0] / 60:.0f} to {ver.change_span_s[1] / 60:.0f} min, the truth's "
        f"{step:.3g}{turns}, the truth's largest departure {away:.3g}); "
        f"kept {np.mean(kept):.2f}; truth explains {share_by_component(d, truth_cols):.3f} "
        f"(coefficients {', '.join(f'{c:.2f}' for c in coef)}); through the maps {mapped}; oracle p {oracle:.3f}"
    )


def oracle_of(sm: SurveyModel, truth: pd.DataFrame) -> float | None:
    """`oracle_p` on the revisits of the fitted model `sm` as diagnose judges them (None: too few)."""
    found = revisits_of(sm)
    if found is None:
        return None
    d0, rp, xy, hd = judged_pairs(sm, found)
    proj = tf.Projector(tf.nuisance(rp, xy, hd))
    return oracle_p(proj(tf.clipped(d0)), rp, proj, truth, sm.survey.t0)


def oracle_p(d: np.ndarray, rp, proj, truth: pd.DataFrame, t0: float, permutations: int = 999) -> float:
    """The permutation p-value of the injected part's own shape in time (one free coefficient per
    component) explaining the projected differences `d`, under the judge's exchanges of stretches."""
    cols = ["level"] if is_level(truth) else ["current_east", "current_north"]
    at = t0 + rp.start_s

    def share(ta: np.ndarray, tb: np.ndarray) -> float:
        g = [np.interp(at + tb, truth.t, truth[c]) - np.interp(at + ta, truth.t, truth[c]) for c in cols]
        return share_by_component(d, [proj(x[:, None]) for x in g])

    obs = share(*rp.times())
    rng = np.random.default_rng(0)
    null = [share(*rp.times(rng.permutation(rp.n_stretches))) for _ in range(permutations)]
    return float((1 + np.sum(np.array(null) >= obs)) / (1 + permutations))


def truth_change(truth: pd.DataFrame, ends: np.ndarray, gain: float) -> tuple[float, float]:
    """The injected part's change from the UNIX time ends[0] to ends[1] (a vector's length), and its
    largest departure from its value at ends[0] between them."""
    grid = np.linspace(ends[0], ends[1], 400)
    cols = ["level"] if is_level(truth) else ["current_east", "current_north"]
    path = gain * np.column_stack([np.interp(grid, truth.t, truth[c]) for c in cols])
    dev = path - path[0]
    step = float(dev[-1, 0]) if len(cols) == 1 else float(np.hypot(*dev[-1]))
    return step, float(np.sqrt((dev**2).sum(axis=1)).max())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("cases", nargs="+", metavar="CASE")
    p.add_argument("--gains", default="0,1,2,3")
    p.add_argument("--cases-dir", type=Path, default=Path("/tmp/forcemap-cases"))
    a = p.parse_args()
    a.cases_dir.mkdir(parents=True, exist_ok=True)
    try:
        for case in a.cases:
            for gain in (float(g) for g in a.gains.split(",")):
                table, truth = scaled_table(case, a.cases_dir, gain)
                if is_level(truth):
                    size = f"{gain * np.ptp(truth.level):.2f} m"
                else:
                    size = f"{gain * np.hypot(truth.current_east, truth.current_north).max():.2f} m/s"
                print(f"{case} {judge_gain(table, truth, gain, size)}", flush=True)
    except (WorkbenchError, FileNotFoundError, KeyError) as e:
        print(f"bench_time_truth: {e}", file=sys.stderr)
        raise SystemExit(2) from None


if __name__ == "__main__":
    main()
