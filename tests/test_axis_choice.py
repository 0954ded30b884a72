"""The spread of the axis choice's error difference over spatial blocks (host/workbench/targets/axis_choice.py)."""

from __future__ import annotations

import numpy as np
from forcemap.host.workbench.targets.axis_choice import AxisChoice, block_sd


def test_independent_samples_give_the_sd_of_a_mean():
    rng = np.random.default_rng(1)
    diff = rng.normal(0.0, 2.0, 20_000)
    blocks = rng.integers(0, 200, len(diff))
    assert abs(block_sd(diff, blocks) / (2.0 / np.sqrt(len(diff))) - 1.0) < 0.2


def test_samples_that_move_together_in_a_block_count_as_one():
    rng = np.random.default_rng(2)
    blocks = np.repeat(np.arange(40), 500)
    diff = rng.normal(0.0, 1.0, 40)[blocks] + rng.normal(0.0, 0.01, len(blocks))
    # 40 independent values, not 20,000: the sd of their mean is about 1 / sqrt(40)
    assert abs(block_sd(diff, blocks) * np.sqrt(40) - 1.0) < 0.3
    assert block_sd(diff[:500], blocks[:500]) == float("inf")  # one block: nothing to judge by


def test_a_difference_within_its_spread_is_said_to_be_alike():
    near = AxisChoice(True, 0.200, 0.199, 1000, 5, mse_diff_sd=0.01)
    far = AxisChoice(True, 0.40, 0.30, 1000, 5, mse_diff_sd=0.01)
    assert not near.clear and "predict alike" in near.line()
    assert far.clear and "alike" not in far.line() and far.to_json()["clear"] is True
