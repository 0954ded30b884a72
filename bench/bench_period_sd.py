"""Is the time judge's period sd the size of its error? Seeds of tests/test_time_judge.py's lap track (a boat
lapping a 400 m x 200 m rectangle for 3 h, AR(1) noise of 30 s, a heading error) with a seiche of known
period, judged as diagnose judges them (bench/RESULTS.md, "The period's sd").

    python -m bench.bench_period_sd [--seeds 1-8] [--periods 3000,4440]

Per seed, the period named and three sds: the profile likelihood's curvature (one independent unit per
crossing), the crossings resampled, and the stretches resampled with a pair weighted by both its stretches'
counts (`time_judge.bootstrap_period_sd`, what the verdict reports). Calibrated sds give errors of about
1 sd: the last line is the RMS of error / sd over every seed.
"""

from __future__ import annotations

import argparse

import numpy as np
from forcemap.host.workbench.timejudge import forms as tf
from forcemap.host.workbench.timejudge.judge import (
    BOOTSTRAP,
    bootstrap_period_sd,
    judge_time,
    refined_period,
)
from forcemap.host.workbench.timejudge.revisits import revisit_pairs, stretch_length

from tests.test_time_judge import lap_track, noise


def crossing_bootstrap_sd(d, ta, tb, period_s: float, rp, proj, seed: int = 0) -> float:
    """The period's sd with whole crossings resampled (pairs of one crossing together)."""
    grid = period_s * np.geomspace(2.0 / 3.0, 1.5, 81)
    C, S = tf.periodic_columns(ta, tb, 2 * np.pi / grid, proj)
    a, b = rp.stretch[rp.pairs[:, 0]], rp.stretch[rp.pairs[:, 1]]
    crossing = np.unique(a * rp.n_stretches + b, return_inverse=True)[1].ravel()
    n = int(crossing.max()) + 1
    rng = np.random.default_rng(seed)
    peaks = []
    for _ in range(BOOTSTRAP):
        w = np.sqrt(np.bincount(rng.integers(0, n, n), minlength=n)[crossing])[:, None]
        peaks.append(grid[int(np.argmax(tf.pair_shares(d * w, C * w, S * w)))])
    return float(np.std(peaks))


def one_seed(period: float, seed: int, track) -> tuple[float, float, float, float] | None:
    """(error of the period named, profile sd, crossings' sd, stretches' sd), or None when no period."""
    t, xy, heading = track
    values = noise(len(t), seed) + 0.1 * np.cos(np.radians(heading))
    values += 0.15 * np.sin(2 * np.pi * t / period)
    rp = revisit_pairs(xy, t, 20.0, stretch_length(t, values - np.median(values)))
    d = values[rp.pairs[:, 1]] - values[rp.pairs[:, 0]]
    v = judge_time(d, rp, xy, heading, permutations=299)
    if v.best.name != "periodic" or v.period_sd_s is None:
        return None
    proj = tf.Projector(tf.nuisance(rp, xy, heading))
    dc = proj(tf.clipped(d[:, None]))
    ta, tb = rp.times()
    _, profile = refined_period(dc, ta, tb, v.best.period_s, max(rp.crossings, 2), proj)
    crossings = crossing_bootstrap_sd(dc, ta, tb, v.best.period_s, rp, proj)
    stretches = bootstrap_period_sd(dc, ta, tb, v.best.period_s, rp, proj)
    return v.best.period_s - period, profile or np.nan, crossings, stretches


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="1-8", help="a range A-B or a list")
    p.add_argument("--periods", default="3000,4440", help="seiche periods (s)")
    a = p.parse_args()
    lo, _, hi = a.seeds.partition("-")
    seeds = range(int(lo), int(hi) + 1) if hi else [int(s) for s in a.seeds.split(",")]
    track = lap_track()
    z = []
    for period in (float(x) for x in a.periods.split(",")):
        for seed in seeds:
            r = one_seed(period, seed, track)
            if r is None:
                print(f"period {period:.0f} s, seed {seed}: no period named", flush=True)
                continue
            err, *sds = r
            z.append([err / s for s in sds])
            print(
                f"period {period:.0f} s, seed {seed}: error {err:+.0f} s; sd profile {sds[0]:.0f}, "
                f"crossings {sds[1]:.0f}, stretches {sds[2]:.0f} s",
                flush=True,
            )
    rms = np.sqrt(np.nanmean(np.square(z), axis=0))
    print(
        f"RMS of error / sd over {len(z)} seeds: profile {rms[0]:.2f}, crossings {rms[1]:.2f}, "
        f"stretches {rms[2]:.2f}"
    )


if __name__ == "__main__":
    main()
