"""The water level under depth (issue 30), measured on the simulator: `python bench/bench_water_level.py`.

One survey: two-hour river surveys (the lawnmower runs its lines about five times) under a 0.7 m tide
(12.42 h period, mid-tide at mid-survey: the level rises 0.68 m), and the same seeds without a tide. For each:
the blocked-CV RMSE of depth (baseline; with the gauge file the simulator writes; with the `water_level`
term), the estimated level against the truth (both centred), and what `diagnose --target depth` finds.

A season (`--season`): 8 surveys over 30 days, 6,000 samples each, the stage following the discharge
through a rating curve (0.6 m range), against the same season with a fixed stage: the per-survey levels
against the truth and the per-survey depth CV.

Figures go to stdout; the numbers in bench/RESULTS.md came from this script.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from forcemap.host.workbench.depth.water_level import (
    crossings,
    level_estimate,
    read_gauge,
    reduce_to_gauge,
)
from forcemap.host.workbench.diagnose.rounds import DIAGNOSE_MAX_BASIS, diagnose
from forcemap.host.workbench.fits.fit import fit_target
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.terms.spec import BASELINE
from forcemap.sim_devices.offline import make_survey


def one_survey(folder: Path, tide: bool, seed: int, duration_s: float) -> dict:
    table = make_survey("river", ["tide"] if tide else [], seed, duration_s, folder)
    s = load_survey(table)
    kw = {"progress": False, "max_basis": DIAGNOSE_MAX_BASIS}
    out = {"seed": seed, "tide": tide, "samples": s.n, "crossings": crossings(s.xy, s.trel)}
    out["cv_baseline"] = fit_target(s, "depth", list(BASELINE), **kw).cv.rmse
    reduced = reduce_to_gauge(load_survey(table), read_gauge(folder / "truth" / "water_level.csv"))
    out["cv_gauge"] = fit_target(reduced, "depth", list(BASELINE), **kw).cv.rmse
    fit = fit_target(s, "depth", list(BASELINE) + ["water_level"], **kw)
    out["cv_water_level"] = fit.cv.rmse
    out["noise_water_level"] = fit.model.primary.noise_std_
    level, sd = level_estimate(fit.model.primary, fit.model.survey.trel)
    truth = np.genfromtxt(folder / "truth" / "samples.csv", delimiter=",", names=True)
    true = np.interp(fit.model.survey.columns["t"], truth["t"], truth["water_level"])
    out["level_range_true"] = float(np.ptp(true))
    out["level_rms_error"] = float(np.sqrt(np.mean((level - (true - true.mean())) ** 2)))
    out["level_sd_mean"] = float(sd.mean())
    d = diagnose(s, "depth", rounds=1, progress=False)
    best = d.candidates[0]
    t = next(c for c in d.candidates if c.covariate == "t")
    out["diagnose_first"] = best.covariate
    out["diagnose_found"] = d.missing_effect_found
    out["t_term"], out["t_revisit_gain"], out["t_blocked_gain"] = (
        t.term,
        t.improvement,
        t.blocked_gain,
    )
    out["t_explanation"] = t.explanation
    return out


def season(folder: Path, stage: float, levels: bool | None) -> dict:
    from forcemap.host.season.levels import rating_check
    from forcemap.host.season.run import run_season
    from forcemap.sim_devices.season import make_season

    paths = make_season(8, 30.0, folder, samples=6000, seed=5, stage_scale_m=stage)
    s = run_season(paths, n_basis=200, levels=levels)
    truth = json.loads((folder / "season_truth.json").read_text())
    st = np.array([x["stage_m"] for x in truth["surveys"]])
    out = {"stage": stage, "levels": levels, "with_levels": s.depth.levels is not None}
    out["rmse_static"] = [c["rmse_static"] for c in s.cv]
    out["rmse_own"] = [c["rmse_own"] for c in s.cv]
    if s.depth.levels is not None:
        err = (s.depth.levels - s.depth.levels.mean()) - (st - st.mean())
        out["level_max_error"] = float(np.abs(err).max())
        out["level_sd"] = s.depth.level_sd.tolist()
        out["rating"] = rating_check(s)["verdict"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--duration", type=float, default=7200.0)
    ap.add_argument("--season", action="store_true", help="the season only")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        if args.season:
            for stage, levels in ((0.98, None), (0.98, False), (0.0, None)):
                t0 = time.perf_counter()
                r = season(root / f"season-{stage}-{levels}", stage, levels)
                print(json.dumps(r), f"({time.perf_counter() - t0:.0f} s)", flush=True)
            return
        for seed in args.seeds:
            for tide in (True, False):
                t0 = time.perf_counter()
                r = one_survey(root / f"s{seed}-{tide}", tide, seed, args.duration)
                print(json.dumps(r), f"({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
