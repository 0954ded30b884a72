"""Issue 28: every real log's physical properties before and after its own calibration.

    python bench/bench_qa.py            # a markdown table for bench/RESULTS.md

"Before" is the import with the instruments as read (``import_to_mcap``, no estimate applied); "after"
is ``forcemap import``'s (``import_calibrated``: the first pass estimates, the second applies what is
safe). Each property is what `forcemap check` computes on the log: the fixes' displacement over SOG x
time (median), the heading's change over the integrated rate of turn, the speed log's gain estimated on
the log (recorded at import, else estimated now), the gain estimated on the samples themselves (1
after calibration when it was applied), the mean current from the speed log (m/s), the share
of depth changes steeper than a seabed (%), and the samples.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from forcemap.host.convert.importers import ImportFailed, import_to_mcap  # noqa: E402
from forcemap.host.convert.self_calibration import import_calibrated  # noqa: E402
from forcemap.host.fuse import redundancy as rd  # noqa: E402
from forcemap.host.qa.report import arrays, check_table  # noqa: E402
from forcemap.host.workbench.survey.table_files import read_raw  # noqa: E402

REAL = ROOT / "tests" / "data" / "real"
GLOBS = ("nmea/*.log", "nmea/*.txt", "nmea/irene/*.nmea", "mavlink/*.tlog", "mavlink/*.BIN")


def props(path: Path) -> dict[str, str]:
    rep = check_table(path)
    got = {(f.category, f.check): f for f in rep.findings}

    def val(key: tuple[str, str], fmt: str) -> str:
        f = got.get(key)
        return "-" if f is None or f.value != f.value else format(f.value, fmt)

    gain = got.get(("speed_through_water", "gain"))
    c = arrays(read_raw(path))
    fit = rd.fit_speed_log(c["t"], c["heading"], c["stw"], c["sog"], c["cog"], c["yaw_rate"])
    return {
        "rows": str(rep.rows),
        "pos/sog": val(("position", "vs_sog"), ".3f"),
        "hdg/rate": val(("rate_of_turn", "unit"), ".2f"),
        "gain": "-"
        if gain is None or gain.value != gain.value
        else f"{gain.value:.3f}" + (" (applied)" if gain.applied else ""),
        "gain on samples": "-" if fit is None else f"{fit.gain:.3f} ± {fit.gain_sd:.3f}",
        "current": val(("speed_through_water", "current_mean"), ".3f"),
        "depth jumps %": val(("depth", "continuity"), ".1f"),
        "verdict": rep.verdict,
    }


def main() -> None:
    logs = sorted(p for g in GLOBS for p in REAL.glob(g))
    keys = ("rows", "pos/sog", "hdg/rate", "gain", "gain on samples", "current", "depth jumps %")
    keys += ("verdict",)
    print("| log | " + " | ".join(f"{k} before / after" for k in keys) + " | import s |")
    print("|---|" + "---|" * (len(keys) + 1))
    for log in logs:
        with tempfile.TemporaryDirectory() as tmp:
            before, after = Path(tmp) / "before.mcap", Path(tmp) / "after.mcap"
            try:
                import_to_mcap(log, before)
            except ImportFailed as e:
                print(f"| {log.name} | no samples: {str(e).split(': ', 1)[-1]} |")
                continue
            t0 = time.process_time()
            import_calibrated(log, after)
            cpu = time.process_time() - t0
            b, a = props(before), props(after)
        cells = " | ".join(f"{b[k]} / {a[k]}" for k in keys)
        print(f"| {log.name} | {cells} | {cpu:.1f} |", flush=True)


if __name__ == "__main__":
    main()
