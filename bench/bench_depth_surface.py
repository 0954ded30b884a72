"""One depth surface (issue 61): on every real NMEA log with depth, the depth fit's noise sd against the
soundings' robust scatter (item 4's: the median over 5-minute windows of the accepted soundings' 1.48 x
MAD about their own least-squares line), its blocked-CV RMSE and its crossline RMSE, and the rows the map
leaves out; with --baseline-src, another checkout's fit of the same tables beside it, its blocked CV
scored on the rows both fit. docs/SOUNDINGS.md, "One depth surface for every map", gives the figures.

    python bench/bench_depth_surface.py [--baseline-src /tmp/before] [--logs DIR] [LOG ...]

Each log is imported and exported once (into --logs, default a temporary folder; an existing
``NAME/log.csv`` there is used as it is), then fitted as `forcemap fit --target depth` fits it
(`fit_target`), in a fresh process per checkout (``--one TABLE OUT.npz``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # `bench.*` when run as a script

LOGS = [
    "nmea/PacCupStartNMEA.txt",
    "nmea/bundg_zeus_9.log",
    "nmea/plaka.log",
    "nmea/NeutronDance.log",
    "nmea/irene/irene_2008-08-20_geneva.nmea",
    "nmea/irene/irene_2013-07-31_flensburg_checksums.nmea",
    "nmea/irene/irene_2013-08-03_flensburg.nmea",
    "nmea/irene/irene_2014-06-27_geneva.nmea",
    "nmea/sfbay/swift-day1.nmea.gz",
    "nmea/sfbay/duxbury.nmea.gz",
]
WINDOW_S = 300.0


def robust_scatter(t: np.ndarray, depth: np.ndarray) -> float:
    """The median over WINDOW_S windows of 1.4826 x the MAD about each window's least-squares line."""
    out = []
    for a in np.arange(t.min(), t.max(), WINDOW_S):
        m = (t >= a) & (t < a + WINDOW_S)
        if m.sum() < 10:
            continue
        r = depth[m] - np.polyval(np.polyfit(t[m] - a, depth[m], 1), t[m] - a)
        out.append(1.4826 * np.median(np.abs(r - np.median(r))))
    return float(np.median(out))


def one(table: Path, out: Path) -> None:
    """Fit depth on ``table`` with whichever forcemap is importable; save the figures and CV to ``out``."""
    import time

    from forcemap.host.fuse.bottom_lost import readings_of
    from forcemap.host.workbench.engine.model import small_blas
    from forcemap.host.workbench.fits import fit as fitting
    from forcemap.host.workbench.survey.table import load_survey

    s = load_survey(table)
    c = time.process_time()
    with small_blas():
        r = fitting.fit_target(s, "depth", ["const", "gp(position, matern32)"], progress=False)
    cpu = time.process_time() - c
    sm = r.model
    so = getattr(sm.rows, "soundings", None)  # the surface's accepted soundings, where there is one
    if so is None:
        d = sm.survey.columns["depth"]
        g = readings_of([d])
        first = np.r_[True, g[1:] != g[:-1]]
        t, z = sm.survey.columns["t"][first], d[first]
    else:
        t, z = so["t"], so["depth"]
    np.savez(
        out, idx=sm.survey.origin[1], pred=r.cv.predicted, y=sm.survey.columns["depth"],
        figures=json.dumps({
            "rows": s.n, "fitted": sm.survey.n, "noise": sm.primary.noise_std_,
            "scatter": robust_scatter(t, z), "cv": r.cv.rmse, "cpu": cpu,
            "crossline": (r.crossline or {}).get("crossline_rmse"),
            "lengthscale": sm.primary.position_lengthscale_,
        }),
    )  # fmt: skip


def table_of(name: str, logs: Path) -> Path:
    """The log's samples table (imported and exported once into ``logs``)."""
    from forcemap.host.cli import main

    folder = logs / name.replace("/", "_").replace(".", "_")
    if not (folder / "log.csv").exists():
        folder.mkdir(parents=True, exist_ok=True)
        capture = ROOT / "tests" / "data" / "real" / name
        lenient = ["--nmea-checksum", "lenient"] if "checksums" in name else []
        assert main(["import", str(capture), "-o", str(folder / "log.mcap"), *lenient]) == 0
        assert main(["export", str(folder / "log.mcap"), "-o", str(folder / "log.csv")]) == 0
    return folder / "log.csv"


def run(table: Path, out: Path, src: str | None) -> dict:
    """`one` in a fresh process, on this checkout or ``src`` (bench_gp's package of symlinks)."""
    import os

    env = dict(os.environ)
    if src:
        from bench.bench_gp import code_path

        env["PYTHONPATH"] = code_path(src, tempfile.mkdtemp()) + os.pathsep + env.get("PYTHONPATH", "")
    cmd = [sys.executable, __file__, "--one", str(table), str(out)]
    subprocess.run(cmd, env=env, check=True, capture_output=True)
    data = np.load(out)
    return {**json.loads(str(data["figures"])), "data": data}


def common_rmse(a, b) -> tuple[float, float]:
    """Each fit's blocked-CV RMSE on the rows both were fitted on."""
    both = np.intersect1d(a["idx"], b["idx"])
    ia, ib = np.searchsorted(a["idx"], both), np.searchsorted(b["idx"], both)
    ea, eb = a["pred"][ia] - a["y"][ia], b["pred"][ib] - b["y"][ib]
    return float(np.sqrt(np.mean(eb**2))), float(np.sqrt(np.mean(ea**2)))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("logs", nargs="*", default=LOGS)
    p.add_argument("--baseline-src", help="another checkout (e.g. `git worktree add /tmp/before main`)")
    p.add_argument("--logs", dest="folder", type=Path, help="where the imported tables are kept")
    p.add_argument("--one", nargs=2, type=Path, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.one:
        one(*args.one)
        return
    folder = args.folder or Path(tempfile.mkdtemp())
    work = Path(tempfile.mkdtemp())
    for name in args.logs:
        table = table_of(name, folder)
        new = run(table, work / "new.npz", None)
        line = (
            f"{name}: rows {new['rows']}, left out {new['rows'] - new['fitted']}, noise {new['noise']:.3f} m, "
            f"scatter {new['scatter']:.3f} m ({new['noise'] / new['scatter']:.2f} x), blocked CV "
            f"{new['cv']:.3f} m, crossline {new['crossline'] or float('nan'):.3f} m, lengthscale "
            f"{new['lengthscale'] or float('nan'):.0f} m, fit {new['cpu']:.1f} s"
        )
        if args.baseline_src:
            old = run(table, work / "old.npz", args.baseline_src)
            cv_old, cv_new = common_rmse(new["data"], old["data"])
            line += (
                f"; base: left out {old['rows'] - old['fitted']}, noise {old['noise']:.3f} m "
                f"({old['noise'] / new['scatter']:.2f} x the scatter here), blocked CV on the rows both fit "
                f"{cv_old:.3f} -> {cv_new:.3f} m, crossline {old['crossline'] or float('nan'):.3f} m, "
                f"lengthscale {old['lengthscale'] or float('nan'):.0f} m, fit {old['cpu']:.1f} s"
            )
        print(line, flush=True)


if __name__ == "__main__":
    main()
