"""What a survey can and cannot tell: `diagnose` on surveys the project makes itself, where the truth is known.

- One pass along one line (the simulator, a two-waypoint mission): time, the distance along the line and
  the heading are one variable. With no effect nothing is found; with a time ramp (a dam release over the
  whole pass) time is flagged as confounded with position, and the advice is to repeat the line later;
  `t`'s line says the track came back too little to judge time where it returns.
- Counters next to a time effect (bench/synth_survey.py with an ensemble number, a wrapping sequence
  counter and a second clock): they are folded into t, which is found; no counter is ever a candidate.
- Two simultaneous effects (depth-driven current and a dam release): found in two rounds, the error falling.
- A weak effect (a dam release of +6 %, gain 10-20 %, under the old fixed 25 % floor): found.
- Realistic leakage (synth.py, the throttle held per leg, so ground speed, course and heading follow the
  current) and no effect: nothing found.
Every case on two seeds.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from forcemap.host.workbench.diagnose.rounds import diagnose
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.timejudge.candidate import MIN_CROSSINGS
from forcemap.sim_devices.offline import make_survey

from bench import synth_survey as synth

SEEDS = (1, 2)
TRANSECT = """[mission]
description = "one pass along the reach"
kind = "waypoints"
points = [[-240.0, 0.0], [220.0, 0.0]]
loop = false
"""
RAMP = "dam_release:start_frac=0.0:end_frac=1.0"


def _transect(tmp_path, effects, seed):
    mission = tmp_path / "transect.toml"
    mission.write_text(TRANSECT)
    table = make_survey("river", effects, seed, 140.0, tmp_path / "s", mission=str(mission))
    return load_survey(table)


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
def test_single_transect_without_effect_finds_nothing(tmp_path, seed):
    survey = _transect(tmp_path, [], seed)
    assert np.ptp(survey.columns["y"]) < 30  # one line: the truth of the case
    d = diagnose(survey, "current_speed", progress=False)
    assert not d.missing_effect_found, d.summary()
    assert len(d.to_json()["rounds"]) == 1


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
def test_single_transect_time_ramp_is_confounded_with_advice(tmp_path, seed):
    d = diagnose(_transect(tmp_path, [RAMP], seed), "current_speed", progress=False)
    assert not d.missing_effect_found, d.summary()
    best = d.candidates[0]
    assert best.covariate == "t" and best.improvement > 0.5, d.summary()
    assert best.identifiable is False and "position" in best.confounded_with, d.summary()
    out = d.to_json()
    assert "repeat" in out["advice"] and "later" in out["advice"]
    assert out["candidates"][0]["identifiable"] is False
    assert "confounded with position" in best.explanation
    # and it says the revisits could not judge it, with how often the line came back
    crossings = re.search(r"\((\d+) crossings and \d+ pairs within", best.note)
    assert crossings and int(crossings.group(1)) < MIN_CROSSINGS, best.note
    assert "judged on blocks" in best.note


COUNTERS = {
    "ens_number": lambda c: np.arange(len(c["t"])) + 1000.0,
    "seq8": lambda c: np.arange(len(c["t"])) % 256.0,  # wraps four times
    "clock_s": lambda c: np.floor(c["t"] - c["t"][0]),
}


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
def test_counters_are_time(tmp_path, seed):
    table = synth.make_survey("river", ["dam_release"], seed, 1200.0, tmp_path, extra=COUNTERS)
    d = diagnose(load_survey(table), "current_speed", rounds=1, progress=False)
    assert d.first.time_proxies == sorted(COUNTERS, key=list(COUNTERS).index), d.summary()
    names = [c.covariate for c in d.candidates]
    assert not set(COUNTERS) & set(names)
    assert d.missing_effect_found and names[0] == "t", d.summary()
    assert "ens_number" in d.candidates[0].explanation  # t's text says what was folded into it
    assert "only counts time" in d.summary()


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
def test_two_effects_are_found_in_two_rounds(tmp_path, seed):
    table = make_survey("river", ["depth_current", "dam_release"], seed, 1200.0, tmp_path)
    d = diagnose(load_survey(table), "current_speed", progress=False)
    rounds = d.to_json()["rounds"]
    added = [r["added"] for r in rounds if r["added"]]
    assert sorted(added) == ["gp(depth, matern32)", "gp(t, matern32)"], d.summary()
    assert len(rounds) == 3 and not rounds[2]["missing_effect_found"], d.summary()
    errors = [r["baseline"]["cv_rmse"] for r in rounds]
    assert errors[0] > errors[1] > errors[2], errors
    assert d.to_json()["candidates"] == rounds[0]["candidates"]  # the top level is the first round


# A release that raises the current by 3.5 %. The gain of the same release varies between surveys, since
# it depends on which blocks each fold holds out (seeds 1-4: 28, 38, 43 and 14 %, Evaluator on the first
# round); the weak cases are the two under 30 %, and the old fixed 25 % floor missed seed 4's
WEAK_SEEDS = (1, 4)


@pytest.mark.slow
@pytest.mark.parametrize("seed", WEAK_SEEDS)
def test_weak_effect_is_found(tmp_path, seed):
    table = make_survey("river", ["dam_release:increase=0.035"], seed, 1200.0, tmp_path)
    d = diagnose(load_survey(table), "current_speed", rounds=1, progress=False)
    best = d.candidates[0]
    assert best.covariate == "t" and d.missing_effect_found, d.summary()
    assert 0.10 <= best.improvement < 0.30, d.summary()
    assert best.improvement > max(best.null_gains), d.summary()


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("target", ["current_speed", "wind_speed"])
def test_throttle_held_per_leg_leaks_nothing(tmp_path, seed, target):
    table = synth.make_survey("river", [], seed, 1200.0, tmp_path, held_throttle=True)
    survey = load_survey(table)
    # the case is real: the ground speed follows the current and the throttle changes leg by leg
    assert np.std(survey.columns["throttle"]) > 3.0  # its noise alone: 2.0
    d = diagnose(survey, target, rounds=1, progress=False)
    assert not d.missing_effect_found, d.summary()
