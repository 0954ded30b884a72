"""Soundings (issue 37): the figures docs/SOUNDINGS.md gives, and the cost of import + grid.

    python bench/bench_soundings.py figures            # the simulator's and the real logs' figures
    python bench/bench_soundings.py timing [LOG ...]   # CPU of `import` + `export` + `grid` per log

``timing`` runs the commands in this process and reports their CPU time (``time.process_time``: every
thread of the process, whatever the machine's load); run it with this checkout's venv and with the
base's, back to back, to compare (bench/RESULTS.md). It only calls the commands both have.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IRENE = ROOT / "tests" / "data" / "real" / "nmea" / "irene" / "irene_2008-08-20_geneva.nmea"


def timing(logs: list[Path], repeat: int) -> None:
    from forcemap.host.cli import main

    for log in logs:
        for i in range(repeat):
            with tempfile.TemporaryDirectory() as d:
                out = {}
                for step, args in (
                    ("import", ["import", str(log), "-o", f"{d}/log.mcap"]),
                    ("export", ["export", f"{d}/log.mcap", "-o", f"{d}/log.csv"]),
                    ("grid", ["grid", f"{d}/log.csv", "-o", f"{d}/maps"]),
                ):
                    t0 = time.process_time()
                    assert main(args) == 0, step
                    out[step] = round(time.process_time() - t0, 2)
                out["total"] = round(sum(out.values()), 2)
                print(json.dumps({"log": log.name, "run": i, "cpu_s": out}), flush=True)


def figures() -> None:
    """The simulator's figures, as tests/test_soundings_sim.py sets them up, and the real logs'."""
    import numpy as np
    from forcemap.host.workbench.survey.spikes import target_spikes
    from forcemap.host.workbench.survey.table import load_survey

    sys.path.insert(0, str(ROOT))
    from tests import test_soundings_sim as t

    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        lost = t.make_survey("strait", [], 1, t.STRAIT_S, d / "lost", faults=f"beyond_range:range={t.RANGE_M}")
        held = t.make_survey("strait", [], 1, t.STRAIT_S, d / "held")
        truth = json.loads((d / "lost" / "truth" / "effects.json").read_text())
        res, survey = t._fit(lost)
        ref, _ = t._fit(held)
        found = [(round(survey.t0 + s.t0 - truth["t0"]), round(survey.t0 + s.t1 - truth["t0"])) for s in res.model.spikes.stretches]
        print(json.dumps({
            "strait": {"lost_share": truth["instruments"]["bottom_lost_soundings"] / t.STRAIT_S,
                       "true": truth["instruments"]["bottom_lost_stretches"], "found": found,
                       "cv_rmse_lost": res.cv.rmse, "cv_rmse_held": ref.cv.rmse,
                       "kept_rmse_lost": _kept_rmse(lost)}}), flush=True)  # fmt: skip
        heel = _heel(d, t)
        print(json.dumps({"heel": heel}), flush=True)
    for log in ("nmea/PacCupStartNMEA.txt", "nmea/irene/irene_2008-08-20_geneva.nmea",
                "nmea/irene/irene_2013-08-03_flensburg.nmea", "nmea/plaka.log",
                "nmea/irene/irene_2014-06-27_geneva.nmea"):  # fmt: skip
        print(json.dumps({"real": log, **_real(ROOT / "tests" / "data" / "real" / log)}), flush=True)
    _ = (np, target_spikes, load_survey)


def _kept_rmse(table: Path) -> float:
    """The blocked-CV RMSE with every sounding kept (--keep-outliers): what the stretch would cost."""
    from forcemap.host.workbench.engine.model import small_blas
    from forcemap.host.workbench.fits.fit import fit_target
    from forcemap.host.workbench.survey.table import load_survey
    from forcemap.host.workbench.terms.spec import BASELINE

    with small_blas():
        return fit_target(load_survey(table, keep_outliers=True), "depth", list(BASELINE), progress=False).cv.rmse


def _heel(d: Path, t) -> dict:
    from forcemap.host.convert.depth_findings import tilt_finding
    from forcemap.host.fuse.calibration import Calibration
    from forcemap.host.vessel import scenario as sc
    from forcemap.host.workbench.diagnose.rounds import diagnose
    from forcemap.host.workbench.engine.model import small_blas
    from forcemap.host.workbench.survey.table import load_survey

    lake = Path(sc.load("lake").path).read_text()
    scenario = d / "windy_lake.toml"
    scenario.write_text(lake.replace("\nspeed = 2.5", "\nspeed = 6.0").replace('name = "lake"', 'name = "windy_lake"'))
    mission = d / "crosslines.toml"
    mission.write_text(t.CROSSLINES)
    tables = {
        name: t._heel_survey(d / name, scenario, mission, effects, beam)
        for name, effects, beam in (("upright", [], None), ("heeled", ["heel"], None), ("corrected", ["heel"], t.BEAM))
    }  # fmt: skip
    out = {f"crossline_{k}": t._crossline(p) for k, p in tables.items()}
    raw = load_survey(tables["heeled"])
    c = {k: raw.columns[k] for k in ("t", "lat", "lon", "depth", "roll", "pitch")}
    f, beam = tilt_finding(c, "depth", Calibration())
    out["beam_estimate"] = {"beam": beam, "sd": f.sd, "message": f.message}
    for c in ("roll", "pitch"):
        raw.columns.pop(c)
    with small_blas():
        for name, s in (("heeled_no_attitude", raw), ("corrected", load_survey(tables["corrected"]))):
            dg = diagnose(s, "depth", rounds=1, progress=False).rounds[0]
            out[f"diagnose_{name}"] = [(c.covariate, round(c.improvement, 3), c.significant) for c in dg.candidates[:3]]
    return out


def _real(path: Path) -> dict:
    from forcemap.host.cli import main

    with tempfile.TemporaryDirectory() as d:
        assert main(["import", str(path), "-o", f"{d}/log.mcap"]) == 0
        assert main(["check", f"{d}/log.mcap", "--json", f"{d}/c.json"]) == 0
        rep = json.loads(Path(f"{d}/c.json").read_text())
    depth = rep["categories"].get("depth", {}).get("findings", [])
    return {f["check"]: f["message"] for f in depth if f["check"] in ("bottom_lost", "s44", "tilt", "sounders")}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("what", choices=("figures", "timing"))
    p.add_argument("logs", nargs="*", type=Path)
    p.add_argument("--repeat", type=int, default=2)
    a = p.parse_args()
    if a.what == "timing":
        timing(a.logs or [IRENE], a.repeat)
    else:
        figures()


if __name__ == "__main__":
    main()
