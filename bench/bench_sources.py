"""Issue 20's simulator figures: one NMEA-only boat with every source fault (a second GNSS, an IIRMC
relay, a damped IIHDT, ROT, false echoes) against the same boat with one clean source of each kind;
and two receivers of different fix quality (`poor_gnss`, `dgps_gnss`): the better one is used.

    python bench/bench_sources.py [--seed 1] [--duration 600]

Speed from successive positions against SOG (p95), yaw rate p99 against the truth's, and the current's
RMS error, through the real pipeline (`tests/sim_sources.py` is the one home of the measurement).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.sim_sources import figures, run  # noqa: E402

RUNS = (
    ("one clean source of each", None),
    ("every source fault", "sources"),
    # the fix quality: an autonomous GP receiver (HDOP 2.1, 2 m error) alone, beside a DGPS GN one
    # (4 decimals: the old order took GP for its 5), and the GN losing its corrections for 120 s
    ("autonomous GP alone", "poor_gnss"),
    ("GP + DGPS GN", "poor_gnss,dgps_gnss"),
    ("GP + GN, corrections lost 200-320 s", "poor_gnss,dgps_gnss:at=200:for=120"),
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--duration", type=float, default=600.0, help="simulated seconds")
    args = ap.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, faults in RUNS:
            paths, truth, _ = run(Path(tmp) / name.replace(" ", "_"), faults, seed=args.seed,
                                  duration_s=args.duration)  # fmt: skip
            rows[name] = figures(paths, truth)
    keys = sorted(next(iter(rows.values())))
    print(f"river, {args.duration:.0f} s, seed {args.seed}")
    print("| figure | " + " | ".join(rows) + " |")
    print("|---|" + "---:|" * len(rows))
    for k in keys:
        cells = [f"{v[k]:.3g}" if isinstance(v[k], float) else str(v[k]) for v in rows.values()]
        print(f"| {k} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
