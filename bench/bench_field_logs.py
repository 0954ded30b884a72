"""Benchmark: a real NMEA capture through the user's commands, import → export → fit → diagnose.

The capture is PacCupStart (a sailing yacht at a race start on San Francisco Bay, NMEA 0183 from its
instruments: VWR, HDM, VHW, VTG/RMC, DBT, MTW; see ../shared/data/real/nmea/PROVENANCE.md). Each step
is the `forcemap` command a user types, run in this process through `forcemap.host.cli.main`; times are
printed as ratios to the import, the baseline measured in the same run.

    python bench/bench_field_logs.py [--capture PATH] [-o /tmp/forcemap-bench-field]
    python bench/bench_field_logs.py --sources-only    # the source and latency figures alone

Then, for every real NMEA capture, the sources per quantity, their disagreement and latency, and
the speed from positions against SOG (bench/field_sources.py, issue 20).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import math
import shutil
import time
from pathlib import Path

from forcemap.host.cli import main as forcemap

from bench.field_sources import report as sources_report

DEFAULT = Path(__file__).resolve().parents[1] / "tests/data/real/nmea/PacCupStartNMEA.txt"
# every real NMEA capture that gives samples (NeutronDance is a corrupted stream kept for robustness)
CAPTURES = ("PacCupStartNMEA.txt", "plaka.log", "bundg_zeus_9.log")
SPIKE_TARGETS = ("depth", "current_speed", "wind_speed", "water_temp", "stw")
TARGETS = ("current_speed", "wind_speed", "depth")
COLUMNS = ("wind_speed", "wind_dir", "depth", "current_speed", "current_dir", "water_temp")


def step(*argv: str) -> tuple[float, str]:
    """Run one forcemap command; its wall time and what it printed on stderr."""
    err = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = forcemap(list(argv))
    dt = time.perf_counter() - t0
    if code != 0:
        raise SystemExit(f"forcemap {' '.join(argv)} failed ({code}):\n{err.getvalue()}")
    return dt, err.getvalue()


def filled(table: Path) -> tuple[int, dict[str, float]]:
    rows = list(csv.DictReader(table.open()))
    share = {}
    for c in COLUMNS:
        ok = [r for r in rows if r.get(c) not in (None, "") and math.isfinite(float(r[c]))]
        share[c] = len(ok) / len(rows)
    return len(rows), share


def data_figures(capture: Path, out: Path) -> None:
    """Spikes flagged per target, and the data-quality findings, of one capture (import, then the MCAP
    read by the workbench, provenance and all)."""
    from forcemap.host.workbench.survey import data_quality
    from forcemap.host.workbench.survey.spikes import target_spikes
    from forcemap.host.workbench.survey.table import load_survey

    mcap = out / (capture.stem + ".mcap")
    step("import", str(capture), "-o", str(mcap))
    survey = load_survey(mcap)
    flagged = []
    for target in SPIKE_TARGETS:
        found = target_spikes(survey, target) if target in survey.columns else None
        if found is not None:
            kinds = ", ".join(f"{n} {why.split(' (')[0]}" for n, why, _ in found.kinds()) or "none"
            flagged.append(f"{target} {found.count} ({kinds})")
    print(f"\n{capture.name}: {survey.n} samples; spikes flagged: " + "; ".join(flagged))
    for f in data_quality.findings(survey, [t for t in SPIKE_TARGETS if t in survey.columns]):
        if f.kind != "spikes":
            print(f"  {f.kind}: {f.text}")


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--capture", type=Path, default=DEFAULT)
    ap.add_argument(
        "-o", "--output", "--out", dest="out", type=Path, default=Path("/tmp/forcemap-bench-field")
    )
    ap.add_argument("--sources-only", action="store_true", help="only the sources' figures")
    ap.add_argument(
        "--data-only",
        action="store_true",
        help="only the spike and data-quality figures of every real capture",
    )
    args = ap.parse_args()
    if args.sources_only:
        print("\n".join(sources_report(args.capture.parent)))
        return
    shutil.rmtree(args.out, ignore_errors=True)
    args.out.mkdir(parents=True)
    if args.data_only:
        data_only(args.capture.parent, args.out)
        return
    mcap, table = args.out / "survey.mcap", args.out / "survey.csv"

    base, _ = step("import", str(args.capture), "-o", str(mcap))
    t_export, _ = step("export", str(mcap), "-o", str(table))
    n, share = filled(table)
    print(f"capture {args.capture.name}: {n} samples")
    print("non-empty: " + ", ".join(f"{c} {100 * s:.0f} %" for c, s in share.items()))
    print(f"\n{'step':<28} {'wall s':>7} {'x import':>9}")
    print(f"{'import':<28} {base:7.1f} {1.0:9.2f}")
    print(f"{'export':<28} {t_export:7.1f} {t_export / base:9.2f}")
    for target in TARGETS:
        dt, _ = step("fit", str(table), "--target", target, "--no-plots")
        print(f"{'fit ' + target:<28} {dt:7.1f} {dt / base:9.2f}")
    diag = args.out / "diagnose.json"
    dt, _ = step("diagnose", str(table), "--target", "current_speed", "--json", str(diag))
    print(f"{'diagnose current_speed':<28} {dt:7.1f} {dt / base:9.2f}")

    hist = json.loads((args.out / "survey.csv.forcemap" / "history.json").read_text())
    print("\nblocked-CV RMSE of the baseline map (const + gp(position)):")
    for h in hist:
        print(
            f"  {h['target']:<14} {h['cv_rmse']:.3f}  (95 % interval coverage {h['coverage95']:.2f})"
        )
    d = json.loads(diag.read_text())
    print(f"\ndiagnose current_speed: missing_effect_found = {d['missing_effect_found']}")
    for c in d["candidates"][:5]:
        extra = ""
        if "identifiable" in c:
            extra = f" identifiable={c['identifiable']} confounded_with={c.get('confounded_with')}"
        print(f"  {c['covariate']:<20} gain {100 * c['improvement']:+5.1f} %{extra}")
    if d.get("advice"):
        print(f"advice: {d['advice']}")
    print("\nsources of every real NMEA capture (issue 20):")
    print("\n".join(sources_report(args.capture.parent)))
    for f in d.get("data_quality", []):
        print(f"data quality, {f['kind']}: {f['text']}")
    print()
    data_only(args.capture.parent, args.out)


def data_only(folder: Path, out: Path) -> None:
    print("spikes and data-quality findings of the real NMEA captures:")
    for name in CAPTURES:
        data_figures(folder / name, out)


if __name__ == "__main__":
    main()
