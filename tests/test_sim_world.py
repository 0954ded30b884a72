"""Scenarios, fields, world effects, missions and the clock file."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
from forcemap.host.acquire.arrival_clock import SimClock, read_anchor, write_anchor
from forcemap.host.vessel import mission, scenario
from forcemap.sim_devices import effects
from forcemap.sim_devices.fields import World

EFFECT_NAMES = [
    "depth_current", "dam_release", "gusts", "bank_shelter",
    "wheel_misalignment", "anemometer_upwash", "heel", "compass_deviation", "clock_offset", "tide",
    "tidal_stream", "reference_stream", "seiche", "stage",
]  # fmt: skip


def grid(w: World) -> tuple[np.ndarray, np.ndarray]:
    x, y = w.grid(121, 41)
    return np.meshgrid(x, y)


def test_catalogue_names_are_the_contract() -> None:
    assert list(effects.CATALOGUE) == EFFECT_NAMES
    assert len(effects.lines()) == len(EFFECT_NAMES)
    e = effects.parse("wheel_misalignment:wheel=2:angle_deg=15")
    assert e.params == {"wheel": 2, "angle_deg": 15.0}
    with pytest.raises(ValueError):
        effects.parse("no_such_effect")
    with pytest.raises(ValueError):
        effects.parse("gusts:nope=1")


def test_river_base_world_matches_the_issue() -> None:
    sc = scenario.load("river")
    w = World(sc, [], 1800.0)
    xx, yy = grid(w)
    d = w.depth(xx, yy)
    assert 0.5 <= d.min() < 1.0 and 5.0 < d.max() <= 6.0
    ce, cn = w.current(xx, yy, 0.0)
    sp = np.hypot(ce, cn)
    assert 0.95 < sp.min() and sp.max() == pytest.approx(2.5, abs=0.01)
    # strongest over the thalweg: the fastest water is where the smooth bed is deepest
    assert np.corrcoef(sp.ravel(), w._smooth_depth(xx, yy).ravel())[0, 1] > 0.99
    # the flow goes downstream (east) everywhere
    assert np.all(ce > 0.9 * sp)
    we, wn = w.wind(xx, yy, np.zeros_like(xx))
    ws = np.hypot(we, wn)
    assert 5.0 <= ws.min() and ws.max() <= 9.0
    # sheltered near the (south) wooded bank
    assert ws[0].mean() < ws[-1].mean() - 1.0
    assert sc.extent[1] - sc.extent[0] == pytest.approx(600.0) and sc.extent[3] - sc.extent[
        2
    ] == pytest.approx(160.0)


def test_a_world_without_an_effect_holds_its_current_and_depth_constant_in_time() -> None:
    """The null surveys of diagnose's tests (and issue 59's power bench) need nothing in time to find: on
    the river and the lake without an effect, the current and the depth at every place are the same at
    every time of a survey, and the water level stays at rest (the wind's gusts are its own business)."""
    for name in ("river", "lake"):
        w = World(scenario.load(name), [], 3600.0, seed=3)
        xx, yy = grid(w)
        first = np.array(w.current(xx, yy, np.zeros_like(xx)))
        for t in (600.0, 1800.0, 3599.0):
            assert np.array_equal(np.array(w.current(xx, yy, np.full_like(xx, t))), first), (name, t)
        assert np.all(w.water_level(np.linspace(0, 3600, 50)) == 0.0), name


def test_depth_current_slows_the_bars() -> None:
    sc = scenario.load("river")
    base = World(sc, [], 600.0)
    on = World(sc, effects.parse_list(["depth_current"]), 600.0)
    xb, yb = base.bars[1][:2]
    b0 = np.hypot(*base.current(xb, yb, 0.0))
    b1 = np.hypot(*on.current(xb, yb, 0.0))
    d = on.depth(xb, yb)
    # Manning: speed ~ depth^(2/3), 2.5 m/s over the deepest water
    assert b1 == pytest.approx(2.5 * (d / on.d_th) ** (2 / 3), rel=1e-9)
    assert b1 < 0.6 * b0  # strong enough to see
    xx, yy = grid(on)
    sp, dd = np.hypot(*on.current(xx, yy, 0.0)), on.depth(xx, yy)
    assert np.corrcoef(np.log(sp.ravel()), np.log(dd.ravel()))[0, 1] > 0.999


def test_dam_release_ramps_discharge() -> None:
    w = World(scenario.load("river"), effects.parse_list(["dam_release"]), 1800.0)
    s0 = np.hypot(*w.current(0.0, 0.0, 0.0))
    s1 = np.hypot(*w.current(0.0, 0.0, 1800.0))
    assert s1 / s0 == pytest.approx(1.6, rel=1e-6)
    ts = np.linspace(0, 1800, 200)
    q = w.discharge_factor(ts)
    assert np.all(np.diff(q) >= 0) and np.max(np.diff(q)) < 0.02  # smooth


def test_gusts_reach_12_on_the_river_but_not_the_lake() -> None:
    for name, lo, hi in (("river", 12.0, 17.0), ("lake", 3.5, 6.0)):
        w = World(scenario.load(name), effects.parse_list(["gusts"]), 1800.0, seed=4)
        ts = np.arange(0, 1800, 0.5)
        ws = np.hypot(*w.wind(np.zeros_like(ts), np.zeros_like(ts), ts))
        assert lo <= ws.max() <= hi, name
    w = World(scenario.load("river"), effects.parse_list(["gusts"]), 1800.0, seed=4)
    ts = np.arange(0, 1800, 0.5)
    ws = np.hypot(*w.wind(np.zeros_like(ts), np.zeros_like(ts), ts))
    # slow swell (tens of minutes) and fast gusts (seconds) both present
    slow = np.convolve(ws, np.ones(600) / 600, mode="valid")
    assert (
        slow.max() - slow.min() > 1.0
        and np.std(ws[600:-600] - slow[300:-300][: len(ws) - 1200]) > 0.5
    )


def test_bank_shelter_comes_and_goes() -> None:
    w = World(scenario.load("river"), effects.parse_list(["bank_shelter"]), 1800.0)
    x = np.zeros(3)
    y = np.array([-75.0, 0.0, 70.0])  # near the wooded south bank, mid-river, north bank
    ts = np.arange(0.0, 1800.0, 10.0)
    frm = w.wind_from_deg(ts)
    ws = np.array([np.hypot(*w.wind(x, y, np.full(3, t))) for t in ts])
    # the wind veers through south (over the wooded bank) and back, more than once
    crossings = np.count_nonzero(np.diff(np.sign(frm - 180.0)) != 0)
    assert crossings >= 4
    over_bank = np.abs(frm - 180.0) < 15.0
    along_bank = np.abs(frm - 270.0) < 15.0
    # near the south bank the wind drops by more than half when it blows from over the bank
    assert ws[over_bank, 0].mean() < 0.5 * ws[along_bank, 0].mean()
    # the shelter fades across the river: the north bank keeps more of the wind
    assert ws[over_bank, 0].mean() < 0.7 * ws[over_bank, 2].mean()


def test_lake_is_calm() -> None:
    w = World(scenario.load("lake"), [], 600.0)
    xx, yy = grid(w)
    assert np.hypot(*w.current(xx, yy, 0.0)).max() < 0.1
    assert np.hypot(*w.wind(xx, yy, np.zeros_like(xx))).max() < 4.0


def test_missions_parallel_and_perpendicular() -> None:
    sc = scenario.load("river")
    par = mission.load("lawnmower", sc).waypoints
    per = mission.load("lawnmower_perpendicular", sc).waypoints
    legs_par = np.diff(par, axis=0)[::2]
    legs_per = np.diff(per, axis=0)[::2]
    assert np.allclose(legs_par[:, 1], 0) and np.all(
        np.abs(legs_par[:, 0]) > 400
    )  # along the flow (east)
    assert np.allclose(legs_per[:, 0], 0) and np.all(np.abs(legs_per[:, 1]) > 80)  # across it
    assert legs_par[0, 0] < 0  # starts from the downstream end, heading upstream
    x0, x1, y0, y1 = sc.survey_box
    for wp in (par, per):
        assert np.all(
            (wp[:, 0] >= x0 - 1e-6)
            & (wp[:, 0] <= x1 + 1e-6)
            & (wp[:, 1] >= y0 - 1e-6)
            & (wp[:, 1] <= y1 + 1e-6)
        )


def test_mission_file(tmp_path: Path) -> None:
    p = tmp_path / "m.toml"
    p.write_text('[mission]\nkind = "waypoints"\nlatlon = [[33.82, -80.85], [33.821, -80.85]]\n')
    m = mission.load(str(p), scenario.load("river"))
    assert m.waypoints[0] == pytest.approx([0.0, 0.0], abs=1e-6)
    assert m.waypoints[1][1] == pytest.approx(110.9, abs=0.5) and abs(m.waypoints[1][0]) < 1e-6


def test_scenario_copy_and_edit(tmp_path: Path) -> None:
    src = scenario.load("river")
    text = Path(src.path).read_text().replace("thalweg = 2.5", "thalweg = 2.0")
    p = tmp_path / "slow_river.toml"
    p.write_text(text)
    w = World(scenario.load(str(p)), [], 60.0)
    xx, yy = grid(w)
    assert np.hypot(*w.current(xx, yy, 0.0)).max() == pytest.approx(2.0, abs=0.01)


def test_clock_file(tmp_path: Path) -> None:
    path = tmp_path / "clock"
    mono = time.monotonic_ns()
    assert read_anchor(path) is None  # not written yet
    write_anchor(path, 1_780_322_400_000_000_000, mono, 50.0)
    assert path.stat().st_size == 24
    assert read_anchor(path) == (1_780_322_400_000_000_000, mono, 50.0)
    c = SimClock(path)
    a = c.now_ns()
    time.sleep(0.01)
    b = c.now_ns()
    assert a >= 1_780_322_400_000_000_000 and b - a >= 50 * 10_000_000 * 0.9
    h = SimClock(path).now_ns()  # a second reader of the same file agrees
    assert b <= h <= c.now_ns()


def test_utc_start() -> None:
    assert scenario.parse_utc("2026-06-01T14:00:00Z") == 1780322400.0
    assert math.isclose(scenario.load("lake").t0, 1780322400.0)


def test_lawnmower_direction_override(tmp_path: Path) -> None:
    p = tmp_path / "ns.toml"
    p.write_text(
        '[mission]\nkind = "lawnmower"\norientation = "parallel"\nspacing = 20.0\ndirection_deg = 0.0\n'
    )
    wps = mission.load(str(p), scenario.load("lake")).waypoints
    legs = np.diff(wps, axis=0)[::2]
    assert np.allclose(legs[:, 0], 0) and np.all(np.abs(legs[:, 1]) == 80.0)  # north-south legs
