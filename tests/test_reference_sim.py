"""A simulated tidal river whose truth is a reference station's prediction times a known ratio and offset
field (the simulator's `reference_stream`, sim_devices/reference_stream.py): three days are flown, the
first two fitted with the tide on the reference (bench/bench_reference_sim.py), the third predicted.

Where the track covers the reach, the recovered ratio must be within 10 % of the truth and the offset
within 10 minutes; the next day's vector error at most 1.5 times the fit's own (issue 60).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.bench_reference_sim import recover, simulated


@pytest.mark.slow
def test_the_ratio_and_offset_field_is_recovered_and_the_next_day_predicted(tmp_path: Path) -> None:
    r = recover(simulated(3, tmp_path / "river"), 3)
    assert r.ratio_err_max < 0.10, r
    assert r.offset_err_max_min < 10.0, r
    assert r.next_day_ratio <= 1.5, r
    assert any("station SFB1204 for every place" in line for line in r.lines)
