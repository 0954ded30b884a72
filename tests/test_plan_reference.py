"""`forcemap plan --start` with a reference current, against the simulator's truth (issue 60).

A river whose own current (x 0.5) carries a tidal stream that is NOAA station SFB1204's prediction times a
ratio (1.5-2.1) and later by an offset that change along the reach (sim_devices/reference_stream.py) is
surveyed for a day. The current is fitted with the tide on the reference (`--reference-current`, the
station chosen); the lawnmower whose lines cross the river is planned for the next day's strongest
stream and flown there in the simulator's true river, with another seed, against a plan from the mean
current. The plan from the reference predicts each line at its own time and must hold the lines at least
20 % better (p95 distance from the intended lines, the worst line).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from forcemap.host.vessel import scenario as sc
from forcemap.host.workbench.survey.reference import load_reference
from forcemap.sim_devices.reference_stream import REFERENCE

from bench.tidal_survey import truth_survey
from tests.test_plan_tide import later_river
from tests.test_plan_tide import plan_and_fly as tide_plan_and_fly

STREAM = ["reference_stream:river=0.5:ratio=1.8:ratio_east=0.3"]
STATION = "SFB1204"


def strongest(after: float, span_s: float = 86400.0) -> float:
    """The time of the station's strongest stream (either way) in the day after `after`."""
    st = load_reference(REFERENCE, STATION).stations[STATION]
    t = after + np.arange(0.0, span_s, 300.0)
    return float(t[int(np.argmax(np.abs(st.speed(t))))])


def plan_and_fly(table: Path, effect: str, start: float, scenario: Path, out: Path):  # type: ignore[no-untyped-def]
    """The lawnmower across the river, planned from the tide on the reference (or the mean current) and
    flown in the true river at `start`."""
    return tide_plan_and_fly(
        table, effect, start, scenario, out, STREAM, "lawnmower_perpendicular", (REFERENCE, STATION)
    )


@pytest.mark.slow
def test_the_plan_from_the_reference_beats_the_plan_from_the_mean_current(tmp_path: Path) -> None:
    # a row every 10 s (17,280 rows a day at the default 5 s): the fits' CPU is 25 s less. Measured at
    # both: the reference plan's p95 worst line 0.28 m (5 s) and 0.30 m (10 s), the mean plan's
    # infinite (a line missed) and 10.3 m: the bound (0.8 x the mean's) holds by a factor of 25 or more
    table = truth_survey("river", STREAM, 3, 86400.0, tmp_path / "survey", every_s=10.0)
    t0 = sc.load("river").t0
    start = strongest(t0 + 86400.0) - 900.0
    scenario = later_river(tmp_path, start)
    mean_maps, mean = plan_and_fly(table, "", start, scenario, tmp_path)
    ref_maps, ref = plan_and_fly(table, "tide", start, scenario, tmp_path)
    assert mean_maps.current.times is None
    assert ref_maps.current.times is not None and ref_maps.current.times[0] == start
    assert any("tide(reference, position)" in n for n in ref_maps.notes)
    # flown in the true river: p95 distance from the lines, worst line, at least 20 % below the mean's
    print(f"p95 worst line: reference {ref.summary['p95_worst_line']:.2f} m, mean {mean.summary['p95_worst_line']:.2f} m")
    assert ref.summary["p95_worst_line"] <= 0.8 * mean.summary["p95_worst_line"], (
        ref.summary,
        mean.summary,
    )
    assert ref.summary["coverage"] >= 0.95 and np.isfinite(ref.summary["p95_worst_line"])
