"""A simulated river whose tide is a reference station's, times a known ratio and offset field: recovered?

    python -m bench.bench_reference_sim [--days 3] [--out DIR] [--seed 3]

The simulator's `reference_stream` effect (sim_devices/reference_stream.py) makes the river's current
NOAA station SFB1204's prediction times ratio(x) = 0.8 + 0.25 xi and later by offset(x) = 20 + 25 xi
minutes (xi: east position over half the reach), with the river's own flow off, so the stream reverses.
The boat mows the reach for DAYS days (bench/tidal_survey.py: the true track with the pipeline's noise,
a row every 10 s). The first DAYS - 1 days are fitted (`fit --target current_speed --effects tide
--reference-current host/data/noaa_sfbay_currents.json --reference-station SFB1204`), the last day is
predicted. Printed: the ratio and offset recovered against the truth where the track covers the reach
(its lines: the survey box less 5 % of its length at each end, where the boat turns; their largest and
95th-percentile errors), and the vector RMSE in sample and on the next day.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from forcemap.host.vessel import scenario as sc
from forcemap.host.vessel.geodesy import LocalFrame
from forcemap.host.workbench.survey.reference import load_reference, with_reference
from forcemap.host.workbench.survey.table import Survey, load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel
from forcemap.host.workbench.terms import time_terms
from forcemap.host.workbench.terms.reference_maps import relation_maps
from forcemap.host.workbench.terms.spec import BASELINE
from forcemap.sim_devices.effects import parse
from forcemap.sim_devices.reference_stream import REFERENCE, ReferenceStream

from bench.tidal_survey import truth_survey

EFFECT = "reference_stream"
SCENARIO = "river"
EVERY_S = 10.0
CORE_MARGIN = 0.05


@dataclass
class Recovery:
    """What one run recovered and predicted."""

    ratio_err_max: float  # |fitted / true - 1| over the track
    ratio_err_p95: float
    offset_err_max_min: float  # |fitted - true| over the track, minutes
    offset_err_p95_min: float
    rmse_in_sample: float  # vector RMSE (m/s), east and north together
    rmse_next_day: float
    lines: list[str]
    fit_cpu_s: float

    @property
    def next_day_ratio(self) -> float:
        return self.rmse_next_day / self.rmse_in_sample


def simulated(days: int, out: Path, seed: int = 3) -> Path:
    """The DAYS-long survey's table (made once into `out`)."""
    return truth_survey(SCENARIO, [EFFECT], seed, days * 86400.0, out, every_s=EVERY_S)


def vector_rmse(sm: SurveyModel, s: Survey, rows: np.ndarray) -> float:
    """RMSE of the model's east and north at `rows` of `s` against the measured ones."""
    frame = LocalFrame(sm.survey.lat0, sm.survey.lon0)
    xy = np.column_stack(frame.to_local(s.columns["lat"][rows], s.columns["lon"][rows]))
    p = sm.predict_grid(xy, at=s.columns["t"][rows])
    de = p["east"] - s.columns["current_east"][rows]
    dn = p["north"] - s.columns["current_north"][rows]
    return float(np.sqrt(np.mean(de**2 + dn**2)))


def truth_at(s: Survey, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The effect's true ratio and offset (s) at the rows' places."""
    scen = sc.load(SCENARIO)
    x, _ = LocalFrame(scen.lat0, scen.lon0).to_local(s.columns["lat"][rows], s.columns["lon"][rows])
    x0, x1 = scen.extent[:2]
    stream = ReferenceStream(parse(EFFECT).params, scen.t0, 0.5 * (x0 + x1), 0.5 * (x1 - x0))
    return stream.truth(x)


def on_the_lines(s: Survey, rows: np.ndarray) -> np.ndarray:
    """Which rows are where the track covers the reach: inside the mission's survey box less CORE_MARGIN
    of its length at each end (the boat turns beyond its lines' ends)."""
    scen = sc.load(SCENARIO)
    x, _ = LocalFrame(scen.lat0, scen.lon0).to_local(s.columns["lat"][rows], s.columns["lon"][rows])
    x0, x1 = scen.survey_box[:2]
    margin = CORE_MARGIN * (x1 - x0)
    return (x > x0 + margin) & (x < x1 - margin)


def recover(table: Path, days: int) -> Recovery:
    """Fit the first DAYS - 1 days with the reference, compare the relation with the truth, predict the
    last day."""
    s = load_survey(table)
    last = s.columns["t"] >= s.columns["t"][0] + (days - 1) * 86400.0
    train = s.subset(~last)
    with_reference(train, load_reference(REFERENCE, "SFB1204"))
    cpu = time.process_time()
    sm = SurveyModel(train, "current_speed", [*BASELINE, "tide"]).fit()
    cpu = time.process_time() - cpu
    idx = np.unique(np.linspace(0, train.n - 1, 800).astype(int))
    idx = idx[on_the_lines(train, idx)]
    along, across = time_terms.along_across(sm)
    maps = relation_maps(along, across, train.xy[idx], time_terms.relation_base(sm, train.xy[idx]))
    ratio, offset = truth_at(train, idx)
    r_err = np.abs(maps["ratio"] / ratio - 1.0)
    o_err = np.abs(maps["offset_s"] - offset) / 60.0
    rng = np.random.default_rng(0)
    test_rows = np.flatnonzero(last)
    train_rows = rng.choice(train.n, min(train.n, 6000), replace=False)
    return Recovery(
        float(r_err.max()), float(np.percentile(r_err, 95)),
        float(o_err.max()), float(np.percentile(o_err, 95)),
        vector_rmse(sm, train, train_rows), vector_rmse(sm, s, test_rows),
        time_terms.describe(sm), cpu,
    )  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--days", type=int, default=3)
    p.add_argument("--seed", type=int, default=3)
    p.add_argument("--out", type=Path, default=Path("/tmp/forcemap-reference-sim"))
    a = p.parse_args()
    cpu = time.process_time()
    table = simulated(a.days, a.out / f"days{a.days}-seed{a.seed}", a.seed)
    print(f"simulated {a.days} days: {table} ({time.process_time() - cpu:.0f} s CPU)", flush=True)
    r = recover(table, a.days)
    print("\n".join(r.lines))
    print(
        f"ratio error over the track: max {r.ratio_err_max:.1%}, p95 {r.ratio_err_p95:.1%}; offset "
        f"error max {r.offset_err_max_min:.1f} min, p95 {r.offset_err_p95_min:.1f} min; vector RMSE "
        f"in sample {r.rmse_in_sample:.3f} m/s, next day {r.rmse_next_day:.3f} m/s "
        f"({r.next_day_ratio:.2f}x); fit {r.fit_cpu_s:.0f} s CPU"
    )


if __name__ == "__main__":
    main()
