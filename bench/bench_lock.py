"""Soundings judged against a smooth bed (issue 61): the figures docs/SOUNDINGS.md gives.

    python bench/bench_lock.py sim      # the simulator's sounder that locks and unlocks, against its truth
    python bench/bench_lock.py real     # every real NMEA log with depth: what was rejected, the scatter kept
    python bench/bench_lock.py map      # the depth map's blocked-CV RMSE, lock lost against bottom held

``sim``: the strait (``--faults lock_loss:range=103``), 12 minutes, seeds 1-3, judged as the import
judges a table (forcemap.host.fuse.sounding_reasons.judge_column), and the same surveys with the bottom
held. ``real``: each log imported and exported in this process, then judged; the scatter of the
soundings kept per 5-minute window, as the issue measures it (1.4826 MAD about the window's own trend
line) and about a running median over a minute (the noise, without the bed's relief); the CPU time of
the judgement. ``map``: the depth map (`forcemap fit`'s baseline terms, blocked CV) of the lock-loss
survey with its rows marked as an import marks them (``bottom_lost``: the workbench leaves out every
row above 0), of the same survey with the bottom held, and of the lock-loss survey left to the
workbench's own spike and bottom-lost tests.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SEEDS = (1, 2, 3)
DURATION_S, RANGE_M = 720.0, 103.0
NMEA = ("nmea/*.log", "nmea/*.txt", "nmea/irene/*.nmea", "nmea/sfbay/*.nmea.gz")


def _survey(folder: Path, seed: int, lost: bool) -> Path:
    from forcemap.sim_devices.offline import make_survey

    faults = f"lock_loss:range={RANGE_M}" if lost else None
    return make_survey("strait", [], seed, DURATION_S, folder, faults=faults)


def _sim_figures(table: Path) -> dict:
    sys.path.insert(0, str(ROOT))
    from forcemap.host.fuse.sounding_reasons import NAMES
    from forcemap.host.workbench.table import load_survey

    from tests.test_sounder_lock import _judged, _truth_per_row

    survey, judged = _judged(table)
    kind, past = _truth_per_row(table, survey)
    truth = json.loads((table.parent / "truth" / "effects.json").read_text())
    reason = judged.row_reasons
    out = {
        "true": truth["instruments"]["bottom_lost_stretches"],
        "found": [[round(survey.t0 + s.t0 - truth["t0"]), round(survey.t0 + s.t1 - truth["t0"])]
                  for s in judged.stretches],  # fmt: skip
        "held_rejected_within_range": round(float((reason[(kind == "held") & ~past] > 0).mean()), 4),
        "held_rejected_past_range": round(float((reason[(kind == "held") & past] > 0).mean()), 4),
    }
    for k in ("scatter", "false_bottom", "second_echo"):
        m = kind == k
        out[k] = {"rows": int(m.sum()), "rejected": round(float((reason[m] > 0).mean()), 4),
                  "as": {NAMES[c]: int((reason[m] == c).sum()) for c in NAMES}}  # fmt: skip
    _ = load_survey
    return out


def sim() -> None:
    with tempfile.TemporaryDirectory() as d:
        for seed in SEEDS:
            lost = _survey(Path(d) / f"l{seed}", seed, True)
            held = _survey(Path(d) / f"h{seed}", seed, False)
            fig = _sim_figures(lost)
            sys.path.insert(0, str(ROOT))
            from tests.test_sounder_lock import _judged

            _, judged = _judged(held)
            fig["held_survey"] = {"stretches": len(judged.stretches),
                                  "rejected": round(float((judged.row_reasons > 0).mean()), 4)}  # fmt: skip
            print(json.dumps({"seed": seed, **fig}), flush=True)


def _noise(t: np.ndarray, d: np.ndarray) -> dict:
    """Per 5-minute window, against the window's median depth: 1.4826 MAD about the window's trend
    line (the issue's measure) and about a running median over a minute."""
    sys.path.insert(0, str(ROOT))
    from tests.test_soundings_judged_real import local_noise

    line = []
    for a in np.arange(t[0], t[-1], 300.0):
        m = (t >= a) & (t < a + 300.0)
        if m.sum() >= 10:
            fit = np.polyval(np.polyfit(t[m] - a, d[m], 1), t[m] - a)
            r = d[m] - fit
            line.append(1.4826 * np.median(np.abs(r - np.median(r))) / np.median(d[m]))
    local = local_noise(t, d)
    return {"trend_line_median": round(float(np.median(line)), 4),
            "local_median": round(float(np.median(local)), 4),
            "local_p90": round(float(np.percentile(local, 90)), 4)}  # fmt: skip


def _columns(path: Path) -> dict[str, np.ndarray]:
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) if r[k] else np.nan for r in rows]) for k in rows[0]}


def real() -> None:
    from forcemap.host.cli import main
    from forcemap.host.convert.depth_findings import judged as judge_table
    from forcemap.host.fuse.sounding_reasons import NAMES

    logs = sorted(p for g in NMEA for p in (ROOT / "tests" / "data" / "real").glob(g))
    for log in logs:
        with tempfile.TemporaryDirectory() as d:
            lenient = ["--nmea-checksum", "lenient"] if "checksums" in log.name else []
            assert main(["import", str(log), "-o", f"{d}/log.mcap", *lenient]) == 0
            assert main(["export", f"{d}/log.mcap", "-o", f"{d}/log.csv"]) == 0
            c = _columns(Path(d) / "log.csv")
        t0 = time.process_time()
        found = judge_table(c)
        cpu = time.process_time() - t0
        have = np.isfinite(c["depth"])
        codes = np.where(have, found.row_reasons, -1)
        kept = have & (codes == 0)
        out = {
            "real": log.name, "soundings": int(have.sum()),
            "share": {NAMES[k]: round(float((codes[have] == k).mean()), 4) for k in NAMES},
            "stretches": [s.text() for s in found.stretches], "judge_cpu_s": round(cpu, 2),
            "kept": _noise(c["t"][kept], c["depth"][kept]),
            "all": _noise(c["t"][have], c["depth"][have]),
        }  # fmt: skip
        print(json.dumps(out), flush=True)


def _fit_rmse(table: Path) -> float:
    from forcemap.host.workbench.fitting import fit_target
    from forcemap.host.workbench.model import small_blas
    from forcemap.host.workbench.spec import BASELINE
    from forcemap.host.workbench.table import load_survey

    with small_blas():
        return fit_target(load_survey(table), "depth", list(BASELINE), progress=False).cv.rmse


def _marked(table: Path, out: Path) -> Path:
    """The table with each row's reason in ``bottom_lost``, as an import writes it."""
    sys.path.insert(0, str(ROOT))
    from tests.test_sounder_lock import _judged

    _, judged = _judged(table)
    with open(table) as f:
        rows = list(csv.reader(f))
    header = rows[0] + ["bottom_lost"]
    codes = judged.row_reasons
    with open(out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for row, code in zip(rows[1:], codes, strict=True):
            w.writerow(row + ["" if code < 0 else str(int(code))])
    return out


def map_() -> None:
    with tempfile.TemporaryDirectory() as d:
        for seed in SEEDS:
            lost = _survey(Path(d) / f"l{seed}", seed, True)
            held = _survey(Path(d) / f"h{seed}", seed, False)
            marked = _marked(lost, Path(d) / f"l{seed}" / "marked.csv")
            print(json.dumps({"seed": seed, "cv_rmse_marked": _fit_rmse(marked),
                              "cv_rmse_held": _fit_rmse(held),
                              "cv_rmse_workbench_only": _fit_rmse(lost)}), flush=True)  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("what", choices=("sim", "real", "map"))
    a = p.parse_args()
    {"sim": sim, "real": real, "map": map_}[a.what]()


if __name__ == "__main__":
    main()
