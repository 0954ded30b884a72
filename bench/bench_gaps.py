"""Benchmark: what gaps cost (issue 36 item 2), as ratios against a baseline in the same process.

1. The season's statistics of depth and current, each on the rows that have it (`stats.masked_stats`),
   against the one statistics of the three columns on every row (`stats.chunk_stats`, what a log without
   gaps costs), on a log-sized array (54,000 rows, the 401-function basis): with no gap, and with the
   current missing on 3 % of the rows.
2. `diagnose --target current_speed` on the real fjord race (tests/data/real/nmea/irene/
   irene_2013-08-03_flensburg.nmea, imported and exported here), whose current, depth, apparent wind and
   instrument wind have gaps: its CPU against the baseline fit of the same target on the same table, and
   the candidates judged on the rows that have them.

    python bench/bench_gaps.py [--skip-real] [-o /tmp/forcemap-bench-gaps]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from forcemap.host.season.stats import chunk_stats, masked_stats
from forcemap.host.workbench.engine.model import small_blas
from forcemap.host.workbench.terms.gp import HilbertGPTerm

REPO = Path(__file__).resolve().parents[1]
FJORD = REPO / "tests/data/real/nmea/irene/irene_2013-08-03_flensburg.nmea"


def _cpu(fn, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        c = time.process_time()
        fn()
        best = min(best, time.process_time() - c)
    return best


def season_statistics(n: int = 54000, basis: int = 400) -> None:
    rng = np.random.default_rng(0)
    Z = rng.uniform(-500.0, 500.0, (n, 2))
    term = HilbertGPTerm(("position",), "matern32", n_basis=basis, dims=2)
    term.setup(Z)

    def feats(z):
        return np.hstack([np.ones((len(z), 1)), term.features(z)])

    Y = rng.normal(size=(n, 3))
    print(
        f"season statistics, {n:,} rows, {basis + 1} features, one BLAS thread, best of 3 (CPU s):"
    )
    for missing in (0.0, 0.03):
        ok_c = rng.uniform(size=n) >= missing
        targets = {"depth": (Y[:, :1], np.ones(n, bool)), "current": (Y[:, 1:], ok_c)}
        with small_blas():
            old = _cpu(lambda: chunk_stats(feats, Z, Y))
            new = _cpu(lambda t=targets: masked_stats(feats, Z, t))
        print(
            f"  current missing on {missing:.0%} of rows: every row {old:.2f} s, each target on its "
            f"rows {new:.2f} s, ratio {new / old:.2f}"
        )


def real_fjord(out: Path) -> None:
    from forcemap.host.cli import main
    from forcemap.host.workbench.diagnose.rounds import diagnose
    from forcemap.host.workbench.fits.fit import fit_target
    from forcemap.host.workbench.survey.table import load_survey
    from forcemap.host.workbench.terms.spec import BASELINE

    out.mkdir(parents=True, exist_ok=True)
    log, table = out / "fjord.mcap", out / "fjord.csv"
    if not table.exists():
        assert main(["import", str(FJORD), "-o", str(log), "--force"]) == 0
        assert main(["export", str(log), "-o", str(table), "--force"]) == 0
    with small_blas():
        c = time.process_time()
        fit = fit_target(load_survey(table), "current_speed", list(BASELINE), progress=False)
        fit_s = time.process_time() - c
        c = time.process_time()
        d = diagnose(load_survey(table), "current_speed", rounds=1, progress=False)
        diag_s = time.process_time() - c
    print(f"the real fjord race ({table}), one BLAS thread:")
    print(f"  {fit.model.rows.lines()[0]}")
    print(
        f"  baseline fit {fit_s:.1f} s CPU, diagnose {diag_s:.1f} s CPU: {diag_s / fit_s:.1f}x; "
        f"{len(d.candidates)} candidates, {len(d.skipped)} skipped"
    )
    for c in d.candidates:
        if c.rows is not None:
            print(
                f"  {c.covariate}: judged on the {c.rows:,} rows that have it, gain {c.improvement:+.1%}"
            )


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--skip-real", action="store_true", help="only the season statistics")
    ap.add_argument("-o", "--output", default="/tmp/forcemap-bench-gaps")
    args = ap.parse_args()
    season_statistics()
    if not args.skip_real:
        real_fjord(Path(args.output))


if __name__ == "__main__":
    main()
