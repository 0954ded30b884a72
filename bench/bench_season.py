"""Benchmark: a season of simulated surveys through `forcemap season`'s pass, in one process and on a
LocalCluster of 1 and 2 single-threaded workers.

Each configuration runs in a fresh Python process (clean peak memory), on the same Parquet tables: the
footprints, the statistics pass with its tree reduction, the models (no depth CV). Reported: wall time of
`run_season` and of each phase (footprints, statistics, models: depth, current, staleness), the speed-up
against one process (whole run and statistics pass), the peak RSS of every worker (and of the client), the
CPU seconds of the client and of every worker (a
loaded machine stretches wall times, not these), the cluster's start (not in the wall time: the one-process baseline has no cluster to start, and has already
imported the code its first log needs; the workers import it while the cluster starts), and the cost per
log of the statistics pass, from which a 27 M-sample season on 16 workers is extrapolated. The one-process
baseline runs with one BLAS thread, like the workers (OPENBLAS/OMP/MKL_NUM_THREADS=1): one core each.

The full measurement (issue 24: 100 surveys of 54,000 samples, one process and 1 and 2 workers; ~3 min on
an idle 2-core machine, plus ~10 s to simulate the season; the JSON line of every run shows all timings):

    python bench/bench_season.py

While developing, a smaller season and fewer runs, reusing the simulated tables:

    python bench/bench_season.py --surveys 12 --dir /tmp/season12 --configs one,2
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ONE_THREAD = {k: "1" for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}


def _peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_config(config: str, folder: Path) -> dict:
    """One configuration, in this process (called in a child by `main`)."""
    from forcemap.host.season.engine import DaskRunner, LocalRunner
    from forcemap.host.season.run import run_season

    paths = sorted(str(p) for p in folder.glob("survey-*/samples.parquet"))
    t0 = time.perf_counter()
    runner = LocalRunner() if config == "one" else DaskRunner(f"local:{config}")
    start = time.perf_counter() - t0
    started = {} if config == "one" else runner.client.run(time.process_time)  # type: ignore[attr-defined]
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        season = run_season(paths, runner, cv=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        workers = (
            [] if config == "one" else sorted(runner.client.run(_peak_rss_mib).values())  # type: ignore[attr-defined]
        )
        # each worker's CPU during the run (not its start and imports)
        worker_cpu = (
            []
            if config == "one"
            else sorted(c - started[w] for w, c in runner.client.run(time.process_time).items())  # type: ignore[attr-defined]
        )
    finally:
        runner.close()
    return {
        "config": config,
        "surveys": len(season.surveys),
        "samples": int(sum(s.n for s in season.surveys)),
        "wall_s": wall,
        "start_s": start,
        "client_cpu_s": cpu,
        "phases_s": season.timings,
        "client_peak_mib": _peak_rss_mib(),
        "worker_peak_mib": workers,
        "worker_cpu_s": worker_cpu,
        "basis": len(season.frame.space.J) + 1,
        "digest": season_digest(season),
    }


def season_digest(season) -> str:  # type: ignore[no-untyped-def]
    """A hash of the season's numbers (the depth and current posteriors, the current's scales and offsets,
    the water levels): equal digests are identical numbers, bit for bit."""
    import hashlib

    h = hashlib.sha256()
    for fit in (season.depth, season.current):
        if fit is None:
            continue
        for a in (
            fit.theta,
            fit.post.mean,
            fit.post.L,
            getattr(fit, "scales", None),
            getattr(fit, "offsets", None),
            getattr(fit, "levels", None),
        ):
            if a is not None:
                h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    return h.hexdigest()[:16]


def make(folder: Path, surveys: int, samples: int) -> float:
    from forcemap.sim_devices.season import make_season

    t0 = time.perf_counter()
    make_season(surveys, 30.0, folder, samples=samples, seed=7)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--surveys", type=int, default=100, help="surveys to simulate (default 100)")
    ap.add_argument(
        "--samples", type=int, default=54_000, help="samples per survey (default 54,000)"
    )
    ap.add_argument("--dir", type=Path, help="reuse (or make) the season here")
    ap.add_argument(
        "--configs",
        default="one,1,2",
        help="runs: `one` (one process) and N (a LocalCluster of N workers); default one,1,2",
    )
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(run_config(args.child, args.dir)))
        return
    folder = args.dir or Path(tempfile.mkdtemp(prefix="bench_season_"))
    if not list(folder.glob("survey-*/samples.parquet")):
        print(
            f"simulating {args.surveys} x {args.samples} samples: {make(folder, args.surveys, args.samples):.0f} s"
        )
    rows = []
    for config in args.configs.split(","):
        env = dict(os.environ, **ONE_THREAD)
        cmd = [sys.executable, __file__, "--child", config, "--dir", str(folder)]
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
        print(json.dumps(rows[-1]), flush=True)
    report(rows)


def report(rows: list[dict]) -> None:
    base = next((r for r in rows if r["config"] == "one"), rows[0])
    print(f"\n{base['surveys']} surveys, {base['samples']:,} samples, basis {base['basis']}")
    print(
        "| run | wall s | footprints s | statistics s | models s (depth, current, staleness) "
        "| speed-up | statistics speed-up | peak MiB per worker | client MiB | client CPU s "
        "| worker CPU s | cluster start s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        ph = r["phases_s"]
        name = "one process" if r["config"] == "one" else f"LocalCluster, {r['config']} worker(s)"
        peaks = ", ".join(f"{p:.0f}" for p in r["worker_peak_mib"]) or "-"
        parts = ", ".join(
            f"{ph.get(k, float('nan')):.2f}" for k in ("depth_s", "current_s", "staleness_s")
        )
        print(
            f"| {name} | {r['wall_s']:.1f} | {ph['footprints_s']:.2f} | {ph['statistics_s']:.1f} | "
            f"{ph['models_s']:.2f} ({parts}) | {base['wall_s'] / r['wall_s']:.2f} | "
            f"{base['phases_s']['statistics_s'] / ph['statistics_s']:.2f} | {peaks} | "
            f"{r['client_peak_mib']:.0f} | {r['client_cpu_s']:.1f} | "
            f"{', '.join(f'{c:.1f}' for c in r['worker_cpu_s']) or '-'} | {r['start_s']:.1f} |"
        )
    if base["config"] == "one":
        print(
            "\nCPU seconds (what a loaded machine does not inflate): the one-process run's CPU against, for each "
            "cluster run, its busiest worker's CPU during the run plus the client's models; "
            "their ratio is the speed-up the run would show with a free core per worker:"
        )
        for r in rows:
            if r["worker_cpu_s"]:
                ideal = max(r["worker_cpu_s"]) + r["phases_s"]["models_s"]
                print(
                    f"  {r['config']} worker(s): {base['client_cpu_s']:.1f} / ({max(r['worker_cpu_s']):.1f} + "
                    f"{r['phases_s']['models_s']:.1f}) = {base['client_cpu_s'] / ideal:.2f}"
                )
    digests = {r["config"]: r.get("digest") for r in rows}
    same = len(set(digests.values())) == 1
    print(
        f"\nthe season's numbers (digest of its posteriors, scales, offsets, levels): {digests}: "
        f"{'identical in every configuration' if same else 'NOT identical'}"
    )
    one = next((r for r in rows if r["config"] == "1"), base)
    per_log = (one["phases_s"]["statistics_s"] + one["phases_s"]["footprints_s"]) / one["surveys"]
    per_sample = per_log / (one["samples"] / one["surveys"])
    logs_27m = 27e6 / (one["samples"] / one["surveys"])
    est = 27e6 * per_sample / 16 + one["phases_s"]["models_s"] * logs_27m / one["surveys"]
    print(
        f"\nper log (footprint + statistics, one worker): {per_log:.2f} s, {per_sample * 1e6:.1f} us/sample;"
        f" 27 M samples ({logs_27m:.0f} logs) on 16 workers: ~{27e6 * per_sample / 16:.0f} s of statistics"
        f" + models (scaled with the number of surveys from this run) = ~{est:.0f} s"
    )


if __name__ == "__main__":
    main()
