"""Time judged where the boat comes back (host/workbench/timejudge/judge.py), on tracks with a known truth.

A boat laps a 400 m x 200 m rectangle at 2 m/s for three hours (one lap in 10 minutes), so it passes every
place 18 times. Its readings carry correlated noise (an AR(1) of 30 s, sd 0.2), a heading-dependent error
(a misaligned sensor) and, in some cases, a change in time. The verdict must find a seiche and its period,
a smooth tide (whose time-shifted copies are the same signal, so no null), a slow drift; and stay null on
noise alone and on a heading error sailed at set times.
"""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.workbench.diagnose.catalogue import time_form_cause
from forcemap.host.workbench.timejudge.judge import Form, TimeVerdict, judge_time
from forcemap.host.workbench.timejudge.revisits import revisit_pairs, stretch_length

SPAN_S = 3 * 3600.0
SPEED = 2.0
# as significant as 299 exchanges can say (diagnose runs 999 against 0.05 over ~20 candidates)
THRESHOLD = 1 / 300  # the smallest p-value 299 exchanges can give


def lap_track(span_s: float = SPAN_S) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, xy, heading) of a boat lapping a rectangle, one sample every 2 s."""
    t = np.arange(0.0, span_s, 2.0)
    corners = np.array([[0, 0], [400, 0], [400, 200], [0, 200], [0, 0]], float)
    legs = np.diff(corners, axis=0)
    lengths = np.hypot(*legs.T)
    s = (SPEED * t) % lengths.sum()
    leg = np.searchsorted(np.cumsum(lengths), s, side="right").clip(max=3)
    along = s - np.r_[0, np.cumsum(lengths)][leg]
    xy = corners[leg] + legs[leg] / lengths[leg, None] * along[:, None]
    heading = np.degrees(np.arctan2(legs[leg, 0], legs[leg, 1])) % 360
    return t, xy, heading


def noise(n: int, seed: int, dt: float = 2.0, tau: float = 30.0, sd: float = 0.2) -> np.ndarray:
    """An AR(1) series with correlation time `tau` and standard deviation `sd`."""
    rng = np.random.default_rng(seed)
    a = np.exp(-dt / tau)
    e = rng.normal(0, sd * np.sqrt(1 - a * a), n)
    out = np.empty(n)
    out[0] = rng.normal(0, sd)
    for i in range(1, n):
        out[i] = a * out[i - 1] + e[i]
    return out


def verdict(values: np.ndarray, t, xy, heading):  # type: ignore[no-untyped-def]
    """The revisits' verdict on `values` (a scalar per row), as diagnose forms it."""
    stretch = stretch_length(t, values - np.median(values))
    rp = revisit_pairs(xy, t, 20.0, stretch)
    d = values[rp.pairs[:, 1]] - values[rp.pairs[:, 0]]
    return judge_time(d, rp, xy, heading, permutations=299)


@pytest.fixture(scope="module")
def track():  # type: ignore[no-untyped-def]
    return lap_track()


def test_a_seiche_is_found_with_its_period(track):
    t, xy, heading = track
    period = 4440.0
    values = (
        noise(len(t), 1) + 0.1 * np.cos(np.radians(heading)) + 0.15 * np.sin(2 * np.pi * t / period)
    )
    v = verdict(values, t, xy, heading)
    assert v.p_value <= THRESHOLD + 1e-12, v
    assert v.best.name == "periodic", v.best
    assert v.period_sd_s is not None and v.period_sd_s < 0.2 * period
    assert abs(v.best.period_s - period) <= 2 * v.period_sd_s, (
        v.best,
        v.period_sd_s,
    )
    # the pairs counted are the pairs judged, and the crossings are the laps that came back
    assert v.pairs > 50 and v.crossings >= 17
    assert 0.0 < v.share < 1.0
    assert_forms_named_by_kind(v)


def test_a_smooth_tide_is_no_null_of_itself(track):
    """An M2 tide over three hours is smooth: its time-shifted copies gain as much as it does, which made it
    'not significant' against them. Exchanging whole stretches' times breaks its link with time, and only
    that."""
    t, xy, heading = track
    tide = 0.3 * np.cos(2 * np.pi * t / 44_714.0 + 0.5)
    v = verdict(noise(len(t), 2) + tide, t, xy, heading)
    assert v.p_value <= THRESHOLD + 1e-12, v
    assert v.best.name in ("drift", "tide"), v.best
    assert_forms_named_by_kind(v)


def test_a_drift_is_found(track):
    t, xy, heading = track
    v = verdict(noise(len(t), 3) + 0.3 * t / SPAN_S, t, xy, heading)
    assert v.p_value <= THRESHOLD + 1e-12, v
    assert v.best.name == "drift", v.best
    assert_forms_named_by_kind(v)


def assert_forms_named_by_kind(v) -> None:  # type: ignore[no-untyped-def]
    """Every form is named by its kind: a period longer than the record is part of a cycle, a drift; a
    tidal period a tide; and the kinds the data cannot tell from the best are other kinds than its own."""
    for f in v.forms:
        if f.period_s is None or f.period_s > v.span_s:
            assert f.name in ("drift", "tide"), f
        else:
            assert f.name in ("periodic", "tide"), f
    assert v.best.name not in v.indistinct, (v.best, v.indistinct)


def test_a_drift_is_told_from_a_period_the_record_holds_or_not(track):
    """A slow rise over the record is fitted as well by a period longer than the record as by the drift's
    quadratic: both are a drift, and neither is "another kind it cannot be told from"."""
    t, xy, heading = track
    v = verdict(noise(len(t), 7) + 0.3 * (t / SPAN_S) ** 2, t, xy, heading)
    assert v.best.name == "drift", v.best
    assert_forms_named_by_kind(v)
    longer = [f for f in v.forms if f.name == "drift" and f.period_s is not None]
    assert longer, "the ladder reaches past the record"
    cause = time_form_cause(v, "current", short_for_tide=False)
    assert "a steady rise or fall" in cause and "from a steady drift" not in cause, cause


def test_a_rise_and_fall_the_record_holds_once_is_told_from_a_steady_one(track):
    """A change that rises and falls back within the record (half a sine over the three hours) is a part
    of a cycle the record does not repeat: a drift, whose start-to-end change is about nothing. The finding
    says how far it departs from its start, as the truth does, and does not call it a steady rise. A steady
    rise of the same size does not turn."""
    t, xy, heading = track
    bump = 0.3 * np.sin(np.pi * t / SPAN_S)
    v = verdict(noise(len(t), 11) + bump, t, xy, heading)
    assert v.p_value <= THRESHOLD + 1e-12 and v.best.name == "drift", v.best
    assert v.best.period_s is not None and abs(v.change) < 0.1, (v.best, v.change)
    assert v.departure_sd > 0 and abs(v.departure - 0.3) <= 2 * v.departure_sd, v
    cause = time_form_cause(v, "current", short_for_tide=False)
    assert "a rise and a fall within the survey" in cause and "steady" not in cause, cause
    steady = verdict(noise(len(t), 11) + 0.3 * t / SPAN_S, t, xy, heading)
    assert steady.departure == 0.0, steady
    assert "a steady rise or fall" in time_form_cause(steady, "current", short_for_tide=False)


def test_a_cause_names_the_period_it_cannot_tell_its_form_from():
    """A drift the revisits cannot tell from a periodic change: the cause names the period of the best
    periodic form (not of a weaker one), and never the drift's own kind."""
    forms = [
        Form("drift", None, 0.22, 0.001),
        Form("periodic", 2820.0, 0.21, 0.001),
        Form("periodic", 1500.0, 0.05, 0.3),
        Form("drift", 9600.0, 0.23, 0.001),
    ]
    v = TimeVerdict(
        pairs=6000, crossings=85, span_s=8640.0, stretch_s=120.0, radius_m=54.0,
        rms_difference=0.35, share=0.2, p_value=0.001, permutations=999,
        best=forms[3], forms=forms, indistinct=["periodic"],
    )  # fmt: skip
    cause = time_form_cause(v, "current", short_for_tide=False)
    assert cause.endswith("the revisits cannot tell it from another period (47 min)"), cause
    assert "from a steady drift" not in cause, cause


@pytest.mark.parametrize("seed", [4, 5, 6])
def test_noise_alone_is_no_change_in_time(track, seed):
    t, xy, heading = track
    v = verdict(noise(len(t), seed) + 0.1 * np.cos(np.radians(heading)), t, xy, heading)
    assert v.p_value > 0.01, v


def test_a_heading_error_on_legs_sailed_at_set_times_is_not_time():
    """Back and forth along one line, north for the first half of each hour, south for the second: a sensor
    that reads 0.3 higher heading north makes every revisit pair of opposite legs differ, in step with the
    clock. The heading harmonics are projected out first, so time is not credited with it."""
    t = np.arange(0.0, SPAN_S, 2.0)
    north = (t % 3600.0) < 1800.0
    y = np.where(north, (t % 1800.0) * 0.5, 900.0 - (t % 1800.0) * 0.5)
    xy = np.column_stack([np.zeros_like(t), y])
    heading = np.where(north, 0.0, 180.0)
    values = noise(len(t), 7) + 0.3 * np.cos(np.radians(heading))
    v = verdict(values, t, xy, heading)
    assert v.p_value > 0.01, v
    # the same error without the heading to project out is (wrongly) a change in time: the test can fail
    stretch = stretch_length(t, values - np.median(values))
    rp = revisit_pairs(xy, t, 20.0, stretch)
    d = values[rp.pairs[:, 1]] - values[rp.pairs[:, 0]]
    assert judge_time(d, rp, xy, None, permutations=299).p_value <= THRESHOLD + 1e-12


@pytest.mark.parametrize("with_heading", [True, False])
def test_the_permutations_shares_are_those_of_the_columns_formed_in_full(track, with_heading):
    """The null's shares come from products over the stretches (time_forms.PermutedTimes); for any
    permutation they equal the least squares of the pairs' permuted columns formed in full."""
    from forcemap.host.workbench.timejudge import forms as tf
    t, xy, heading = track
    values = noise(len(t), 3) + 0.2 * np.cos(2 * np.pi * t / 4000.0)
    rp = revisit_pairs(xy, t, 20.0, stretch_length(t, values - np.median(values)))
    proj = tf.Projector(tf.nuisance(rp, xy, heading if with_heading else None))
    d = proj(tf.clipped((values[rp.pairs[:, 1]] - values[rp.pairs[:, 0]])[:, None]))
    ladder = tf.FormLadder(float(np.ptp(rp.t)), rp.stretch_s)
    rng = np.random.default_rng(5)
    orders = np.array([rng.permutation(rp.n_stretches) for _ in range(20)])
    null = tf.PermutedTimes(rp, ladder, proj).null(d, orders)
    for order, fast in zip(orders, null, strict=True):
        ta, tb = rp.times(order)
        full = ladder.shares(d, ta, tb, proj)
        np.testing.assert_allclose(fast, full, rtol=1e-9, atol=1e-12)
    assert null[:, 1:].max() > 0.01  # the shares are not all zero: the test can fail


def test_the_evidence_counts_the_crossings_a_change_rests_on():
    """A change fitted at one crossing rests on one, whatever its number of pairs; a change seen alike at
    every crossing rests on all of them; and the crossing that carries most is named by its passes' times."""
    from forcemap.host.workbench.timejudge.judge import evidence
    from forcemap.host.workbench.timejudge.revisits import RevisitPairs

    t = np.array([0.0, 10.0, 100.0, 110.0, 200.0, 210.0, 300.0, 310.0])
    stretch = np.array([0, 0, 1, 1, 2, 2, 3, 3])
    # crossings (0, 3) with four pairs, (1, 2) and (0, 1) with one each
    pairs = np.array([[0, 6], [1, 7], [0, 7], [1, 6], [2, 4], [0, 2]])
    rp = RevisitPairs(pairs, stretch, 4, 100.0, 3.0, t)
    at_start_and_end = np.array([1.0, 1, 1, 1, 0, 0])[:, None]
    n, (a, b) = evidence(0.6 * at_start_and_end, rp, at_start_and_end)
    assert n == pytest.approx(1.0) and (a, b) == (5.0, 305.0)
    everywhere = np.array([0.5, 0.5, 0.5, 0.5, 1.0, 1.0])[:, None]  # each crossing's pairs add to 1
    n, _ = evidence(0.6 * everywhere, rp, everywhere)
    assert n == pytest.approx(3.0)


def test_a_p_value_near_its_threshold_is_resolved_with_more_exchanges(track):
    """999 exchanges cannot tell a p-value of 0.003 from a threshold of 0.05 / 24 = 0.0021 (two
    exceedances against one or none); a verdict asked for a threshold near its p-value draws exchanges up
    to MAX_PERMUTATIONS, the first ones the same. A threshold far from the p-value costs nothing more."""
    from forcemap.host.workbench.timejudge.judge import MAX_PERMUTATIONS, undecided

    assert undecided(0.003, 999, 0.05 / 24) and undecided(0.001, 999, 0.05 / 24)
    assert undecided(0.018, 999, 0.05 / 24)  # the fjord level's p-value from one seed of 999
    assert not undecided(0.0022, MAX_PERMUTATIONS, 0.05 / 24)  # drawn in full already
    assert not undecided(0.4, 999, 0.05 / 24) and undecided(0.4, 999, 0.42)
    # the band narrows as more are drawn: a p-value a quarter of the threshold is decided at 3,999
    assert undecided(0.0005, 1999, 0.002) and not undecided(0.0005, 3999, 0.002)
    t, xy, heading = track
    values = noise(len(t), 4) + 0.1 * np.cos(np.radians(heading))
    stretch = stretch_length(t, values - np.median(values))
    rp = revisit_pairs(xy, t, 20.0, stretch)
    d = values[rp.pairs[:, 1]] - values[rp.pairs[:, 0]]
    first = judge_time(d, rp, xy, heading, permutations=299)
    far = judge_time(d, rp, xy, heading, permutations=299, threshold=0.05 / 24)
    assert far.permutations == 299 and far.p_value == first.p_value
    near = judge_time(d, rp, xy, heading, permutations=299, threshold=first.p_value)
    assert near.permutations == MAX_PERMUTATIONS
    se = np.sqrt(first.p_value * (1 - first.p_value) / 299)
    assert abs(near.p_value - first.p_value) < 4 * se, (near.p_value, first.p_value)
