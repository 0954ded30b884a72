"""The time judge's power against the bound (issue 59, item 3): changes in time of known shape put into real
logs, the share the revisits' judge names, beside the share a judge that knows the shape finds.

    python -m bench.bench_time_power [LOG ...] [--shapes 20] [--nulls 20] [--cases-dir DIR]

A LOG is a real NMEA log under tests/data/real with a heading and a speed log (default: the four Irene
races: Geneva 2014 and 2008, Flensburg 2013-07-31 and 2013-08-03). Each is imported and exported once as a
user does (tests/real_cases.py). On each, the current model diagnose starts from (const + a GP in
position) gives the revisits' residual differences, as `diagnose` judges them. A log's own record may
change in time (a lake's wind set-up): then any shape put in is "named". So each shape goes into the log
with its stretches' times exchanged at random (nothing of its own left in time, the pairs' differences
and their noise kept), NULLS exchanges per log, each judged bare (a null) and with its shapes:

- a current in time along a random direction: a seiche of 20-240 min at a random phase, a drift (a
  ramp over the record), or an M2 tide at a random phase, its amplitude log-uniform in 0.05-0.4 m/s, at
  the rows' moved times;
- its part the maps leave (the east and north models with their hyperparameters fitted to it alone, as
  bench_time_truth's `kept`) is added to the differences, since a current in time that a map of position
  carries never reaches the revisits;
- `judge_time` at diagnose's threshold (0.05 over 20 candidates) names it or not;
- the bound (`bench_time_truth.oracle_p`): the shape known, its size free, against the same exchanges of
  whole stretches' times.

Power is the share named among the shapes whose bound's p <= 0.001; the nulls' share named is the false
findings' rate. This is the judge alone: `diagnose` also ranks time among the other candidates
(tests/test_time_judge_real.py holds that on single cases).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from forcemap.host.workbench.errors import WorkbenchError
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.timejudge import forms as tf
from forcemap.host.workbench.timejudge.candidate import judged_pairs, revisits_of
from forcemap.host.workbench.timejudge.judge import M2_S, judge_time
from forcemap.host.workbench.timejudge.revisits import RevisitPairs

from bench.bench_time_truth import component_models, oracle_p, through_map
from bench.inject_cases import FJORD, FLENSBURG_31, GENEVA, GENEVA_2008

LOGS = (GENEVA, GENEVA_2008, FLENSBURG_31, FJORD)
# diagnose's threshold with its usual twenty candidates
THRESHOLD = 0.05 / 20
BOUND = 0.001
AMPLITUDE = (0.05, 0.4)  # m/s, log-uniform
PERIOD_MIN = (20.0, 240.0)


@dataclass
class Shape:
    """A current in time: its kind, size (m/s), direction it flows toward (deg), period (s) and phase."""

    kind: str  # "seiche", "drift", "tide"
    amplitude: float
    toward_deg: float
    period_s: float | None = None
    phase: float = 0.0
    span_s: float = 3600.0  # a drift goes from -amplitude to +amplitude over it

    def along(self, trel: np.ndarray) -> np.ndarray:
        """The current's signed size along its direction at times `trel` (s since the survey's start)."""
        if self.kind == "drift":
            return self.amplitude * (np.asarray(trel) / self.span_s - 0.5) * 2.0
        return self.amplitude * np.sin(2 * np.pi * trel / self.period_s + self.phase)

    def label(self) -> str:
        period = "" if self.period_s is None else f" {self.period_s / 60:.0f} min"
        return f"{self.kind}{period} {self.amplitude:.3f} m/s"


def shapes(n: int, rng: np.random.Generator, span_s: float) -> list[Shape]:
    """n shapes: half seiches, a quarter drifts over `span_s`, a quarter tides, each at a random size and
    direction."""
    out = []
    for i in range(n):
        amp = float(np.exp(rng.uniform(*np.log(AMPLITUDE))))
        toward, phase = float(rng.uniform(0, 360)), float(rng.uniform(0, 2 * np.pi))
        if i % 4 in (0, 1):
            period = 60.0 * float(np.exp(rng.uniform(*np.log(PERIOD_MIN))))
            out.append(Shape("seiche", amp, toward, period, phase))
        elif i % 4 == 2:
            out.append(Shape("drift", amp, toward, span_s=span_s))
        else:
            out.append(Shape("tide", amp, toward, M2_S, phase))
    return out


def exchange(rp: RevisitPairs, trel: np.ndarray, rng: np.random.Generator) -> tuple[RevisitPairs, np.ndarray]:
    """The same pairs with whole stretches' times exchanged at random (nothing of the log's own left in
    time to find), and every row's time (s since the survey's start) moved with its stretch."""
    order = rng.permutation(rp.n_stretches)
    shift = rp.shifts(order)
    moved = RevisitPairs(
        rp.pairs, rp.stretch, rp.n_stretches, rp.stretch_s, rp.radius_m, rp.t + shift[rp.stretch], rp.start_s
    )
    stretch = np.clip(((trel - rp.start_s) // rp.stretch_s).astype(int), 0, rp.n_stretches - 1)
    return moved, trel + shift[stretch]


def judge_log(log: str, cases: Path, n_shapes: int, n_nulls: int, seed: int) -> list[dict]:
    """The log as recorded, then NULLS exchanges of its stretches' times, each judged bare (a null) and
    with every shape put in at the moved times (its power): one dict each."""
    from tests.real_cases import Cases

    sm = SurveyModel(load_survey(Cases(cases)(log).csv), "current_speed", None, max_basis=600).fit()
    found = revisits_of(sm)
    if found is None:
        raise WorkbenchError(f"{log}: the track comes back too little to judge time")
    d0, rp, xy, hd = judged_pairs(sm, found)
    proj = tf.Projector(tf.nuisance(rp, xy, hd))
    s = sm.survey
    v = found.rows[rp.pairs]
    rng = np.random.default_rng(seed)
    own = judge_time(d0, rp, xy, hd, threshold=THRESHOLD)
    rows = [dict(log=log, shape="as recorded", kind="log", p=own.p_value, bound=np.nan, form=own.best.name)]
    models = component_models(sm)
    every = shapes(n_shapes, rng, float(np.ptp(s.trel)))
    for i in range(n_nulls):
        moved, t_rows = exchange(rp, s.trel, rng)
        ver = judge_time(d0, moved, xy, hd, threshold=THRESHOLD, seed=i + 1)
        rows.append(dict(log=log, shape="null", kind="null", p=ver.p_value, bound=np.nan, form=ver.best.name))
        todo = every[i::n_nulls]  # the shapes put into this exchange
        parts = _through_maps(models, todo, t_rows)
        for k, sh in enumerate(todo):
            d = d0 + np.column_stack([p[v[:, 1], k] - p[v[:, 0], k] for p in parts])
            ver = judge_time(d, moved, xy, hd, threshold=THRESHOLD, seed=i + 1)
            bound = oracle_p(proj(tf.clipped(d)), moved, proj, _truth(s, sh), s.t0)
            rows.append(
                dict(log=log, shape=sh.label(), kind=sh.kind, p=ver.p_value, bound=bound, form=ver.best.name)
            )
    return rows


def _through_maps(models: list[SurveyModel], todo: list[Shape], t_rows: np.ndarray) -> list[np.ndarray]:
    """Each shape's east and north parts at the rows' times `t_rows` that the maps leave (one column per
    shape): a current in time that a map of position carries never reaches the revisits."""
    unit = np.column_stack([sh.along(t_rows) for sh in todo])
    ang = np.radians([sh.toward_deg for sh in todo])
    return [through_map(m, unit * trig(ang)) for m, trig in zip(models, (np.sin, np.cos), strict=True)]


def _truth(s, sh: Shape) -> pd.DataFrame:
    """The shape as `oracle_p` reads a truth: UNIX time and the current's east and north components."""
    grid = np.arange(-3600.0, np.ptp(s.trel) + 3 * 3600.0, 5.0)  # beyond the record: times moved there
    along = sh.along(grid)
    ang = np.radians(sh.toward_deg)
    t = grid + s.t0
    return pd.DataFrame(
        {"t": t, "current_east": along * np.sin(ang), "current_north": along * np.cos(ang), "level": 0.0}
    )


def summary(rows: list[dict]) -> list[str]:
    """Power where the bound's p <= BOUND, by kind and in all; the nulls' rate of findings."""
    df = pd.DataFrame(rows)
    named = df.p <= THRESHOLD
    own = df[df.kind == "log"].set_index("log").p
    out = [f"  {Path(log).name} as recorded: p {p:.4f}" for log, p in own.items()]
    injected = ~df.kind.isin(["null", "log"])
    strong = injected & (df.bound <= BOUND)
    for kind in ("seiche", "drift", "tide"):
        k = strong & (df.kind == kind)
        if k.any():
            out.append(f"  {kind}: named {int(named[k].sum())} of {int(k.sum())} the bound finds at p <= {BOUND}")
    weak = injected & ~strong
    out.append(
        f"power: {named[strong].mean():.0%} ({int(named[strong].sum())} of {int(strong.sum())}) where the "
        f"bound's p <= {BOUND}; below it, named {int(named[weak].sum())} of {int(weak.sum())}"
    )
    nulls = df.kind == "null"
    out.append(
        f"nulls: named {int(named[nulls].sum())} of {int(nulls.sum())} ({named[nulls].mean():.0%}) at p <= "
        f"{THRESHOLD:.4f}"
    )
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("logs", nargs="*", metavar="LOG", default=list(LOGS))
    p.add_argument("--shapes", type=int, default=20, help="shapes per log (default 20)")
    p.add_argument("--nulls", type=int, default=20, help="exchanged nulls per log (default 20)")
    p.add_argument("--cases-dir", type=Path, default=Path("/tmp/forcemap-cases"))
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    a.cases_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    try:
        for i, log in enumerate(a.logs):
            clock = time.process_time()
            got = judge_log(log, a.cases_dir, a.shapes, a.nulls, a.seed + i)
            for r in got:
                mark = "named" if r["p"] <= THRESHOLD else "-"
                print(f"{Path(log).name}: {r['shape']}: p {r['p']:.4f} ({r['form']}), bound {r['bound']:.4f} {mark}")
            print(f"{Path(log).name}: {time.process_time() - clock:.0f} s of CPU", flush=True)
            rows += got
    except (WorkbenchError, FileNotFoundError, KeyError) as e:
        print(f"bench_time_power: {e}", file=sys.stderr)
        raise SystemExit(2) from None
    print("\n".join(summary(rows)))


if __name__ == "__main__":
    main()
