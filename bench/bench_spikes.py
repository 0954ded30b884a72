"""Benchmark: false echoes in a depth map, three ways. Removal (the workbench's default: spikes flagged along
the track and left out), a heavy-tailed Student-t likelihood by iteratively reweighted least squares, and
nothing (--keep-outliers).

The survey is bench.synth_survey's river reach moved to 80 m of water, with a share of the soundings
replaced by false shallow echoes of 3-20 m (their rows known). Each way's map is compared with the true
bottom at the survey's positions; the noise it reports with the sounder's (DEPTH_NOISE); times are in the
same process, as ratios to removal.

The Student-t fit uses pseudo-observations (y* = f + w r with the t weights w = (nu + 1) / (nu + (r/s)^2)):
for a Gaussian-process posterior mean, their fixed point is the weighted least-squares fit IRLS converges
to, and each step is one ordinary fit of the same model, hyperparameters included.

    python bench/bench_spikes.py [--seeds 1 2 3] [--rate 0.08] [--nu 4] [--stretch 0.3 0.7 0.6]

``--stretch LO HI RATE`` adds a stretch (its start and end as shares of the survey) where the echoes
are RATE of the soundings: above 0.5 they are the local majority (issue 20's depth reference).
Each seed's flags are scored against the echo rows: precision and recall.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from forcemap.host.workbench.engine.model import small_blas
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel

from bench.synth_survey import DEPTH_NOISE, LAT0, LON0, depth_field, make_survey

DEEP = 80.0
IRLS_STEPS = 8


def truth_at(survey) -> np.ndarray:
    """The true bottom under each sample (the generator's frame from lat/lon)."""
    r = 6_371_008.8
    lat, lon = survey.columns["lat"], survey.columns["lon"]
    y = np.radians(lat - LAT0) * r
    x = np.radians(lon - LON0) * r * math.cos(math.radians(LAT0))
    return DEEP + depth_field(x, y)


def student_t(survey, nu: float) -> tuple[np.ndarray, float]:
    """The Student-t map at the samples (every row, echoes included) and its noise scale."""
    sm = SurveyModel(survey, "depth").fit()
    X, y = sm.X, sm.y_primary
    # start from a robust line: the running median along the track (a Gaussian fit is 20 m off)
    from forcemap.host.fuse.bottom_lost import running
    from forcemap.host.workbench.survey.spikes import WINDOW

    f = running(y, WINDOW, np.nanmedian)
    model = sm.primary
    for _ in range(IRLS_STEPS):
        r = y - f
        s = 1.4826 * float(np.median(np.abs(r))) or 1e-6
        w = (nu + 1.0) / (nu + (r / s) ** 2)
        model = sm.new_primary().fit(X, f + w * r)
        f = model.predict(X)
    return f, s


def score(path: Path, flagged: np.ndarray, stretch) -> None:
    """The flags' precision and recall against the echo rows (and within the stretch)."""
    rows = json.loads((path.parent / "truth" / "effects.json").read_text())["false_echo_rows"]
    truth = np.zeros(len(flagged), bool)
    truth[rows] = True
    parts = {"all": slice(None)}
    if stretch:
        parts["stretch"] = slice(int(stretch[0] * len(truth)), int(stretch[1] * len(truth)))
    for name, part in parts.items():
        f, t = flagged[part], truth[part]
        hit = int((f & t).sum())
        print(
            f"     flags ({name}): {int(t.sum())} echoes in {len(t)} soundings ({t.mean():.0%}), "
            f"{int(f.sum())} flagged, precision {hit / max(1, f.sum()):.3f}, recall {hit / max(1, t.sum()):.3f}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--rate", type=float, default=0.08)
    ap.add_argument("--nu", type=float, default=4.0)
    ap.add_argument("--duration", type=float, default=1800.0)
    ap.add_argument("--stretch", type=float, nargs=3, metavar=("LO", "HI", "RATE"))
    args = ap.parse_args()
    print(
        f"false echoes: {args.rate:.0%} of the soundings, 3-20 m in {DEEP:g} m of water; sounder noise {DEPTH_NOISE} m"
    )
    print(
        f"{'seed':>4} {'way':<14} {'rows fitted':>11} {'noise m':>8} {'map RMSE m':>10} {'p99 |err| m':>11} {'wall s':>7} {'x removal':>9}"
    )
    with tempfile.TemporaryDirectory() as tmp, small_blas():
        for seed in args.seeds:
            path = make_survey(
                "river",
                [],
                seed,
                args.duration,
                Path(tmp) / str(seed),
                deep_m=DEEP,
                false_echo_rate=args.rate,
                echo_stretch_at=tuple(args.stretch) if args.stretch else None,
            )
            rows = []
            t0 = time.perf_counter()
            clean = SurveyModel(load_survey(path), "depth").fit()
            t_rem = time.perf_counter() - t0
            score(path, clean.spikes.flagged, args.stretch)
            mu = clean.primary.predict(clean.X)
            rows.append(
                (
                    "removal",
                    clean.survey.n,
                    clean.primary.noise_std_,
                    mu - truth_at(clean.survey),
                    t_rem,
                )
            )
            kept = load_survey(path, keep_outliers=True)
            t0 = time.perf_counter()
            raw = SurveyModel(kept, "depth").fit()
            t_raw = time.perf_counter() - t0
            rows.append(
                (
                    "none",
                    raw.survey.n,
                    raw.primary.noise_std_,
                    raw.primary.predict(raw.X) - truth_at(kept),
                    t_raw,
                )
            )
            t0 = time.perf_counter()
            f, s = student_t(kept, args.nu)
            rows.append(
                (
                    f"student-t nu={args.nu:g}",
                    kept.n,
                    s,
                    f - truth_at(kept),
                    time.perf_counter() - t0,
                )
            )
            for way, n, noise, err, wall in rows:
                print(
                    f"{seed:>4} {way:<14} {n:>11} {noise:>8.3f} {np.sqrt(np.mean(err**2)):>10.3f} "
                    f"{np.percentile(np.abs(err), 99):>11.3f} {wall:>7.1f} {wall / t_rem:>9.2f}"
                )


if __name__ == "__main__":
    main()
