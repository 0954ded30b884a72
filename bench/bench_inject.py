"""The injected real cases of issue 36, from the repository's root: `python bench/bench_inject.py`.

Builds every case of bench/inject_cases.py and the clean log it is compared with, exactly as the
tests do (tests/real_cases.py: bench/inject_nmea.py, `forcemap import`, `forcemap export`), and
prints:

- the CPU seconds of each build (injection, import and export together);
- the recovery fits of bench/inject_verify.py (2-minute means against the truth; the difference from
  the clean table and the injected table alone), the figures bench/RESULTS.md gives;
- with `--diagnose`, what `forcemap diagnose` says today on each case and on its clean log (the
  current's case with `--target current_speed`, the level's with `--target depth`).

`--unseen` builds instead the cases on logs that no test case and no threshold was built on
(bench/inject_cases.py's UNSEEN). `--dir DIR` keeps the builds (and reuses them on a second run); by default they go to a temporary
folder.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from forcemap.host.cli import main as forcemap  # noqa: E402

from bench.inject_cases import INJECTED, UNSEEN, case  # noqa: E402
from bench.inject_nmea import read_truth  # noqa: E402
from bench.inject_verify import read_table, recovery  # noqa: E402
from tests.real_cases import Cases  # noqa: E402


def build(cases: Cases, name: str) -> float:
    """Build one case (if not built yet); its CPU seconds."""
    t = time.process_time()
    cases(name)
    return time.process_time() - t


def diagnose(csv: Path, target: str) -> str:
    """`forcemap diagnose` in this process: its verdict lines, or its one-line refusal."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = forcemap(["diagnose", str(csv), "--target", target])
    text = out.getvalue() if rc == 0 else err.getvalue()
    return f"exit {rc}\n" + "\n".join("    " + ln for ln in text.strip().splitlines())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dir", type=Path, help="keep the builds here (default: a temporary folder)")
    p.add_argument("--diagnose", action="store_true", help="also run forcemap diagnose on each")
    p.add_argument("--only", nargs="*", help="cases (default: every case of the tests)")
    p.add_argument(
        "--unseen", action="store_true", help="the cases on logs no test case was built on"
    )
    args = p.parse_args()
    args.only = args.only or sorted(UNSEEN if args.unseen else INJECTED)
    unknown = sorted(set(args.only) - set(INJECTED) - set(UNSEEN))
    if unknown:
        p.error(f"no such case: {', '.join(unknown)} (cases: {', '.join(sorted({**INJECTED, **UNSEEN}))})")
    root = args.dir or Path(tempfile.mkdtemp(prefix="forcemap-inject-"))
    root.mkdir(parents=True, exist_ok=True)
    cases = Cases(root)
    print(f"builds in {root}")
    for name in args.only:
        c = case(name)
        cpu = build(cases, c.clean), build(cases, name)
        built, clean = cases(name), cases(c.clean)
        print(f"\n## {name}: {c.source}, CPU {cpu[1]:.1f} s (its clean log {cpu[0]:.1f} s)")
        eff = c.effect
        if eff.current:
            cur = eff.current
            print(f"current (m/s, toward {cur.toward_deg:g} deg): {cur.shape.describe()}")
        if eff.level:
            print(f"level (m): {eff.level.describe()}")
        table = read_table(str(built.csv))
        fits = recovery(table, read_truth(built.truth), read_table(str(clean.csv)), c.toward_deg)
        print(f"rows {len(table['t'])}")
        for f in fits:
            print("  " + f.line())
        if args.diagnose:
            target = "depth" if eff.level and not eff.current else "current_speed"
            for label, b in (("injected", built), ("clean", clean)):
                t = time.process_time()
                said = diagnose(b.csv, target)
                cpu_s = time.process_time() - t
                print(f"diagnose --target {target} ({label}, {cpu_s:.0f} s CPU): {said}")
    summary = {n: str(cases(n).folder) for n in args.only}
    print("\n" + json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
