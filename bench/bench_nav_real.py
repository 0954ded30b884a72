"""The navigation figures of docs/NAVIGATION.md (issue 29), from the repository's root:

- `python bench/bench_nav_real.py sim`: tests/test_live_navigation's simulated survey through the
  real daemon; p95 of its live rows against the log's re-import and against the truth, after the
  warm-up and over every row.
- `python bench/bench_nav_real.py real`: speed from successive rows against each receiver's own SOG
  on every real NMEA log.

Each log is imported twice, with the pipeline's rows as they were made (the chosen source's last
fix) and with `forcemap run`'s live filter; the table then gives the p95 of |speed from rows at
least 1 s apart - the receiver's raw SOG at the lag the smoother measured| (m/s) for those rows
and for the log's smoothed re-import, with the row counts. The measure is
tests/test_navigation_real.against_sog, the one the tests assert.
"""

from __future__ import annotations

import functools
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from forcemap.host.convert import importers  # noqa: E402
from forcemap.host.convert.export import samples_table  # noqa: E402
from forcemap.host.fuse.pipeline import Pipeline  # noqa: E402

from tests.test_navigation_real import LOGS, _columns, against_sog, receiver_sog  # noqa: E402
from tests.tools import real_data  # noqa: E402


def real() -> None:
    """Print one line per log: rows (logged, live), p95 (logged, live, smoothed)."""
    folder = Path(tempfile.mkdtemp())
    print("log | rows logged | rows live | logged | live | smoothed (m/s, p95)")
    for name, checksum in LOGS.items():
        got = {}
        for live in (False, True):
            importers.Pipeline = functools.partial(Pipeline, live_filter=live)
            out = folder / f"{name.replace('/', '_')}_{live}.mcap"
            importers.import_to_mcap(real_data() / name, out, nmea_checksum=checksum)
            got[live] = _columns(samples_table([out], navigation="logged"))
        smoothed = _columns(samples_table([out]))
        _, t, sog, lag = receiver_sog(out)
        p95 = [against_sog(c, t, sog, lag) for c in (got[False], got[True], smoothed)]
        print(
            f"{name} | {len(got[False]['t'])} | {len(got[True]['t'])} | "
            + " | ".join(f"{v:.2f}" for v in p95),
            flush=True,
        )


def sim() -> None:
    """Print the live rows' p95 differences from the re-import and from the truth."""
    import numpy as np
    from forcemap.host.vessel.geodesy import LocalFrame

    from tests.test_live_navigation import WARM_UP_S, _xy, columns, live_run

    paths, truth, _, timed = live_run(Path(tempfile.mkdtemp()))
    live = columns(samples_table(paths, navigation="logged"))
    again = columns(samples_table(paths))
    t = live["t"]
    late = t > t[0] + WARM_UP_S
    frame = LocalFrame(float(np.nanmedian(live["lat"])), float(np.nanmedian(live["lon"])))
    (x, y), (x2, y2) = _xy(frame, live), _xy(frame, again)
    diffs = {
        "position (m)": np.hypot(x - x2, y - y2),
        "SOG (m/s)": np.abs(live["sog"] - again["sog"]),
        "heading (deg)": np.abs((live["heading"] - again["heading"] + 180) % 360 - 180),
        "stw (m/s)": np.abs(live["stw"] - again["stw"]),
    }
    print("live vs re-import, p95 after the warm-up | over every row")
    for k, d in diffs.items():
        print(f"  {k}: {np.percentile(d[late], 95):.3f} | {np.percentile(d, 95):.3f}")
    frame = LocalFrame(float(truth["lat"][0]), float(truth["lon"][0]))
    x, y = _xy(frame, live)
    tx, ty = frame.to_local(
        np.interp(t, truth["t"], truth["lat"]), np.interp(t, truth["t"], truth["lon"])
    )
    speed = np.hypot(np.diff(x), np.diff(y)) / np.diff(t)
    true_sog = np.interp(0.5 * (t[1:] + t[:-1]), truth["t"], truth["sog"])
    true_hdg = np.interp(t, truth["t"], np.degrees(np.unwrap(np.radians(truth["heading"]))))
    print("live vs truth, p95 after the warm-up")
    print(f"  position {np.percentile(np.hypot(x - tx, y - ty)[late], 95):.2f} m")
    print(f"  speed from rows {np.percentile(np.abs(speed - true_sog)[late[1:]], 95):.2f} m/s")
    hdg = np.abs((live["heading"] - true_hdg + 180) % 360 - 180)
    print(f"  heading {np.percentile(hdg[late], 95):.1f} deg")
    print(f"rows left {min(timed.waits):.2f}-{max(timed.waits):.2f} s after their time")


if __name__ == "__main__":
    {"sim": sim, "real": real}[sys.argv[1] if len(sys.argv) > 1 else "real"]()
