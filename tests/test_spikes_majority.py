"""False echoes as the local majority (issue 20): depth's spike reference is the seabed's continuous
path along the track (forcemap.host.fuse.seabed), not a running median that follows the echoes
where they outnumber the bottom. Known truth: bench.synth_survey's echo rows, and the simulator's
deep basin where every sounding of 3-20 m is an echo."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.fuse.bottom_lost import running
from forcemap.host.fuse.seabed import seabed_path
from forcemap.host.workbench.engine.model import small_blas
from forcemap.host.workbench.survey.spikes import WINDOW, find_spikes
from forcemap.host.workbench.survey.table import load_survey
from forcemap.host.workbench.targets.target_model import SurveyModel

from bench.synth_survey import DEPTH_NOISE, make_survey

STRETCH = (0.3, 0.7)  # of the survey: where the echoes are `rate` of the soundings


def _stretch_survey(tmp_path: Path, seed: int, rate: float) -> tuple[Path, np.ndarray]:
    out = tmp_path / f"s{seed}_{rate}"
    path = make_survey(
        "river",
        [],
        seed,
        1800.0,
        out,
        deep_m=80.0,
        false_echo_rate=0.08,
        echo_stretch_at=(*STRETCH, rate),
    )
    rows = json.loads((out / "truth" / "effects.json").read_text())["false_echo_rows"]
    return path, np.array(rows, int)


@pytest.mark.parametrize(("seed", "rate"), [(1, 0.6), (2, 0.6), (3, 0.8)])
def test_echoes_that_outnumber_the_seabed_are_flagged_and_the_map_is_the_sounders(
    tmp_path, seed, rate
):
    path, rows = _stretch_survey(tmp_path, seed, rate)
    survey = load_survey(path)
    truth = np.zeros(survey.n, bool)
    truth[rows] = True
    lo, hi = (int(f * survey.n) for f in STRETCH)
    # the setting: in the stretch the echoes are the majority, and so the 9-sounding median
    # is an echo (shallower than 30 m) for most of its soundings
    assert truth[lo:hi].mean() > 0.55
    median = running(survey.columns["depth"], WINDOW, np.nanmedian)
    assert (median[lo:hi] < 30.0).mean() > 0.5
    with small_blas():
        sm = SurveyModel(survey, "depth").fit()
    flagged = sm.spikes.flagged
    for part in (slice(None), slice(lo, hi)):
        f, t = flagged[part], truth[part]
        precision, recall = (f & t).sum() / f.sum(), (f & t).sum() / t.sum()
        assert precision >= 0.99 and recall >= 0.99, (part, precision, recall)
    # the map's noise is the clean survey's (the same survey without echoes: the sounder's
    # DEPTH_NOISE, within the 0.05-0.06 m a survey's fit makes of it)
    clean = make_survey("river", [], seed, 1800.0, tmp_path / "clean", deep_m=80.0)
    with small_blas():
        ref = SurveyModel(load_survey(clean), "depth").fit()
    assert abs(ref.primary.noise_std_ / DEPTH_NOISE - 1.0) < 0.25
    assert abs(sm.primary.noise_std_ / ref.primary.noise_std_ - 1.0) < 0.2, (
        sm.primary.noise_std_,
        ref.primary.noise_std_,
    )


@dataclass
class Track:
    """What find_spikes reads of a survey."""

    trel: np.ndarray
    keep_outliers: bool = False
    cache: dict = field(default_factory=dict)


def _flags(depth: np.ndarray) -> np.ndarray:
    return find_spikes(Track(np.arange(len(depth), dtype=float)), "depth", [depth], "depth").flagged


def test_the_path_follows_steps_and_bars_and_leaves_spikes_off():
    rng = np.random.default_rng(0)
    base = np.r_[np.full(100, 5.0), np.full(100, 10.0)] + 0.03 * rng.standard_normal(200)
    assert not _flags(base).any()  # a channel edge is the seabed
    bar = base.copy()
    bar[40:46] -= 2.0  # a bar 6 soundings wide: followed, as the running median of 9 does
    assert not _flags(bar).any()
    echoes = base.copy()
    echoes[[30, 31, 32, 150]] = [1.0, 1.4, 0.8, 3.0]  # a run of 3 shallow echoes and one alone
    echoes[120] = 19.0  # a second echo: deep
    assert set(np.flatnonzero(_flags(echoes))) == {30, 31, 32, 120, 150}
    on = seabed_path(echoes, 0.5 + 0.05 * np.abs(echoes))
    assert not on[[30, 31, 32, 120, 150]].any() and on.sum() == 195


def test_a_long_run_without_the_bottom_is_bridged_by_continuity():
    """40 soundings in a row are echoes (3-20 m) in 80 m of water, some of them close to each
    other: the path bridges the run from the bottom before it to the bottom after it."""
    rng = np.random.default_rng(3)
    depth = 80.0 + 0.05 * rng.standard_normal(300) + np.linspace(0, 3, 300)
    depth[130:170] = rng.uniform(3.0, 20.0, 40)
    depth[140:146] = 15.0 + 0.2 * rng.standard_normal(6)  # a fish school: 6 close echoes
    assert set(np.flatnonzero(_flags(depth))) == set(range(130, 170))


def test_the_simulators_deep_basin_where_most_soundings_are_echoes(tmp_path):
    """The simulator's sounder in its deep basin (70-100 m) with false echoes at 0.6 per sounding:
    every sounding of 3-20 m is flagged as a spike, no other; the depth surface rejects few of the
    bed's (host/workbench/depth/accepted.py), and the map's noise is the clean survey's."""
    from forcemap.sim_devices.offline import make_survey as simulate_survey

    noisy = simulate_survey("deep", [], 1, 600.0, tmp_path / "e", faults="false_echoes:rate=0.6")
    clean = simulate_survey("deep", [], 1, 600.0, tmp_path / "c")
    survey = load_survey(noisy)
    shallow = survey.columns["depth"] < 21.0
    assert shallow.mean() > 0.55
    with small_blas():
        sm = SurveyModel(survey, "depth").fit()
        ref = SurveyModel(load_survey(clean), "depth").fit()
    surface = sm.spikes.surface if sm.spikes.surface is not None else np.zeros(survey.n, bool)
    assert np.array_equal(sm.spikes.flagged & ~surface, shallow)
    assert not (surface & shallow).any() and surface.sum() < 0.1 * (~shallow).sum()
    assert abs(sm.primary.noise_std_ / ref.primary.noise_std_ - 1.0) < 0.2
