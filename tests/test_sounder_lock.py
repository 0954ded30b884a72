"""Soundings judged against a smooth bed, on the simulator's sounder that locks and unlocks (issue 61).

The strait (70 m at its sides, 108 m along its middle) under the lawnmower along it, with a sounder
whose range is 103 m in a rough sea (``--faults lock_loss:range=103``): past its range, over the middle
line, it holds the bottom in short runs between scatter and false bottoms, about a fifth of the survey;
within it, the rough sea brings second echoes at twice the depth, false bottoms and spikes. Every ping's
truth is in ``truth/soundings.csv``. The judgement (forcemap.host.fuse.sounding_reasons) runs on the
samples table as the import runs it, and is compared with that truth, on three seeds; the same survey
with the bottom held all along is judged too.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.fuse.sounding_reasons import (
    FALSE_BOTTOM,
    HELD,
    LOST,
    SECOND_ECHO,
    judge_column,
)
from forcemap.host.workbench.table import load_survey
from forcemap.sim_devices.sounder_lock import LockModel

from tests.sim_surveys import simulated

DURATION_S = 720.0
RANGE_M = 103.0
SEEDS = (1, 2, 3)


def _judged(table: Path):
    """The table's soundings judged, as the import judges them (positions in metres)."""
    survey = load_survey(table)
    return survey, judge_column(survey.columns["depth"], survey.trel, survey.xy)


def _truth_per_row(table: Path, survey) -> tuple[np.ndarray, np.ndarray]:
    """Each row's ping in truth/soundings.csv: its kind and whether the bed was past the range (the
    ping the row carries: sent before it, with the row's reading)."""
    with open(table.parent / "truth" / "soundings.csv") as f:
        pings = list(csv.DictReader(f))
    t = np.array([float(p["t"]) for p in pings])
    value = np.array([float(p["reading"]) for p in pings])
    rows_t = survey.t0 + survey.trel
    depth = survey.columns["depth"]
    kind = np.full(survey.n, "", dtype=object)
    past = np.zeros(survey.n, bool)
    k = np.searchsorted(t, rows_t) - 1
    for i in range(survey.n):
        for j in range(k[i], max(k[i] - 4, -1), -1):  # the last pings sent before the row
            if abs(value[j] - depth[i]) < 0.006:
                kind[i], past[i] = pings[j]["kind"], pings[j]["past"] == "1"
                break
    return kind, past


@pytest.fixture(scope="module")
def surveys(tmp_path_factory):
    """Per seed: the survey with the sounder losing lock, judged, with its truth."""
    out = {}
    for seed in SEEDS:
        table = simulated(
            tmp_path_factory, "strait", [], seed, DURATION_S, faults=f"lock_loss:range={RANGE_M}"
        )
        survey, judged = _judged(table)
        kind, past = _truth_per_row(table, survey)
        truth = json.loads((table.parent / "truth" / "effects.json").read_text())
        out[seed] = (survey, judged, kind, past, truth)
    return out


def test_the_sounder_loses_lock_for_a_fifth_of_the_survey_and_says_so(surveys):
    for _, _, kind, _, truth in surveys.values():
        lock = truth["instruments"]["sounder_lock"]
        assert 0.15 <= lock["past_range_pings"] / DURATION_S <= 0.25
        # past its range the bottom comes in short runs between scatter and false bottoms
        assert 0.15 <= lock["held_past_range"] / lock["past_range_pings"] <= 0.6
        assert lock["pings"]["second_echo"] > 0 and lock["pings"]["false_bottom"] > 0
        assert (kind != "").mean() > 0.99  # every row's ping found in the truth


def test_the_stretch_is_found_within_a_minute_of_its_true_ends(surveys):
    for seed, (survey, judged, _, _, truth) in surveys.items():
        (a, b), *more = truth["instruments"]["bottom_lost_stretches"]
        assert not more
        found = [(survey.t0 + s.t0 - truth["t0"], survey.t0 + s.t1 - truth["t0"])
                 for s in judged.stretches]  # fmt: skip
        assert len(found) == 1, (seed, found)
        assert abs(found[0][0] - a) <= 60.0 and abs(found[0][1] - b) <= 60.0, (seed, found, a, b)


def test_what_the_sounder_did_not_hold_is_rejected_and_what_it_held_is_kept(surveys):
    for seed, (_, judged, kind, past, _) in surveys.items():
        reason = judged.row_reasons
        rejected = reason > HELD
        for k, share in (("scatter", 0.9), ("false_bottom", 0.8), ("second_echo", 0.85)):
            assert rejected[kind == k].mean() >= share, (seed, k, rejected[kind == k].mean())
        # within its range, the bottom it held is kept
        assert rejected[(kind == "held") & ~past].mean() <= 0.05, seed
        # second echoes and false bottoms are named so (inside a lost stretch, a false bottom too
        # short to stand out as a layer of its own is the bottom lost)
        echo = kind == "second_echo"
        assert (reason[echo] == SECOND_ECHO).mean() >= 0.75, (seed, np.unique(reason[echo]))
        fb = kind == "false_bottom"
        named = (reason[fb] == FALSE_BOTTOM) | (past[fb] & (reason[fb] == LOST))
        assert named.mean() >= 0.5, (seed, np.unique(reason[fb], return_counts=True))


def test_the_same_survey_with_the_bottom_held_keeps_it(tmp_path_factory):
    for seed in SEEDS:
        table = simulated(tmp_path_factory, "strait", [], seed, DURATION_S)
        _, judged = _judged(table)
        assert not judged.stretches
        assert (judged.row_reasons > HELD).mean() <= 0.03, seed


def test_the_lock_model_holds_in_runs_past_its_range_and_at_once_within_it():
    lock = LockModel(range_m=50.0, sea=0.0, seed=4)
    for t in range(600):
        depth = 60.0 if 200 <= t < 400 else 40.0
        lock.reading(depth, depth, float(t))
    kinds = [p.kind for p in lock.pings]
    assert set(kinds[:200]) == {"held"} and set(kinds[400:]) == {"held"}  # a calm sea, within range
    past = kinds[200:400]
    assert past[0] != "held"  # past its range it loses the bottom at once
    held = np.array([k == "held" for k in past])
    runs = np.diff(np.flatnonzero(np.diff(np.r_[0, held.astype(int), 0])))[::2]
    assert 0.2 <= held.mean() <= 0.5 and runs.mean() < 10  # short runs between the scatter
    scatter = [p.reading for p in lock.pings[200:400] if p.kind == "scatter"]
    assert min(scatter) >= 4.0 and max(scatter) <= 50.0  # uniform over its range
