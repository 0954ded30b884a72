"""Issue 28 on the simulator, whose truth is known: a speed log that reads 6 % low with its axis turned
2 deg, a dead speed log, a rate gyro that sends deg/s. The estimators find each from the log's own data,
and the current after calibration is as good as with a clean speed log."""

from __future__ import annotations

import numpy as np
import pytest
from forcemap.host.convert.self_calibration import estimate
from forcemap.host.fuse.calibration import Calibration
from forcemap.host.log.mcap import read_messages
from forcemap.host.workbench.survey.table_files import mcap_provenance
from forcemap.sim_devices.engine import Simulation
from forcemap.sim_devices.offline import run_to_mcap

from tests.sim_sources import NMEA_ONLY, figures

DURATION_S = 600.0
GAIN, MISALIGN = 1.06, 2.0


def _run(out, faults, scenario, boat=None):
    sim = Simulation(
        scenario=scenario, faults=faults, seed=1, truth_dir=out / "truth", nmea_bus=True
    )
    paths = run_to_mcap(sim, DURATION_S, out / "logs", seed=1, ports=NMEA_ONLY, boat=boat)
    truth = np.genfromtxt(out / "truth" / "samples.csv", delimiter=",", names=True)
    return paths, truth


def _estimate(paths):
    rows = [m.message for m in read_messages(paths, "/samples")]
    est = estimate(rows, mcap_provenance(paths[-1]), Calibration())
    return {(f.category, f.check): f for f in est.findings}, est.calibration


@pytest.fixture(scope="module")
def lake(tmp_path_factory):
    """The lake with a clean speed log, with the faulty one, and the faulty one calibrated."""
    root = tmp_path_factory.mktemp("lake")
    clean = _run(root / "clean", None, "lake")
    faulty = _run(root / "faulty", f"speed_log:gain={GAIN}:misalign={MISALIGN}", "lake")
    found, cal = _estimate(faulty[0])
    fixed = _run(root / "fixed", f"speed_log:gain={GAIN}:misalign={MISALIGN}", "lake", boat=cal)
    return clean, faulty, found, cal, fixed


def test_speed_log_gain_and_misalignment_are_the_truth(lake):
    _, _, found, cal, _ = lake
    f = found[("speed_through_water", "gain")]
    assert abs(f.value / GAIN - 1) < 0.01, f.message
    assert abs(float(f.extra["misalignment_deg"]) - MISALIGN) < 0.5, f.message
    assert f.applied and cal.stw_gain == f.value


def test_the_current_after_calibration_is_as_good_as_with_a_clean_log(lake):
    clean, faulty, _, _, fixed = lake
    e_clean = figures(*clean)["current_rmse"]
    e_faulty = figures(*faulty)["current_rmse"]
    e_fixed = figures(*fixed)["current_rmse"]
    assert e_faulty > 1.05 * e_clean  # the fault matters (turns dominate the clean error)
    print(f"current RMSE clean {e_clean:.3f}, faulty {e_faulty:.3f}, calibrated {e_fixed:.3f} m/s")
    assert e_fixed <= 1.10 * e_clean, (e_clean, e_faulty, e_fixed)


def test_a_clean_log_is_left_as_it_is(lake):
    (paths, _), *_ = lake
    found, _ = _estimate(paths)
    f = found[("speed_through_water", "gain")]
    assert f.verdict == "green" and abs(f.value - 1) < 0.01, f.message


@pytest.fixture(scope="module")
def gyro_and_dead(tmp_path_factory):
    root = tmp_path_factory.mktemp("gyro")
    paths, truth = _run(root, "rot_deg_s,dead_log:at=200:for=120", "river")
    found, cal = _estimate(paths)
    return paths, truth, found, cal


def test_a_rate_of_turn_in_deg_per_s_is_detected(gyro_and_dead):
    _, _, found, cal = gyro_and_dead
    f = found[("rate_of_turn", "unit")]
    assert f.extra["unit"] == "deg/s" and 30 < f.value < 120, f.message
    assert f.source == "nmea TIROT" and cal.rot_unit == "deg/s"


def test_a_dead_speed_log_is_red_and_dropped(gyro_and_dead):
    paths, truth, found, cal = gyro_and_dead
    f = found[("speed_through_water", "dead")]
    assert f.verdict == "red" and f.applied
    t0 = truth["t"][0]
    (a, b), *more = cal.stw_dead
    assert not more
    # the truth: 0.00 kn from 200 s for 120 s (the log's 1 Hz readings bound it within 2 s)
    assert abs(a - t0 - 200) < 2.5 and abs(b - t0 - 319) < 2.5, (a - t0, b - t0)


def test_after_calibration_the_rate_agrees_and_no_current_comes_from_the_dead_log(
    tmp_path, gyro_and_dead
):
    _, truth, _, cal = gyro_and_dead
    paths, truth = _run(tmp_path, "rot_deg_s,dead_log:at=200:for=120", "river", boat=cal)
    fig = figures(paths, truth)
    assert 0.5 < fig["yaw_rate_p99"] / fig["truth_yaw_rate_p99"] < 2.0
    rows = [m.message for m in read_messages(paths, "/samples")]
    ((a, b),) = cal.stw_dead
    inside = [r for r in rows if a + 2 < r["t"] < b - 2]
    assert inside and all(r.get("current_speed_stw") is None for r in inside)
    assert len(rows) >= DURATION_S  # no row is lost


def test_a_boat_file_pins_the_speed_log_and_the_estimate_is_only_reported(lake):
    from forcemap.host.fuse import calibration

    _, (paths, _), *_ = lake
    rows = [m.message for m in read_messages(paths, "/samples")]
    pinned = calibration.loads("[speed_log]\ngain = 1.0\n[rate_of_turn]\nunit = 'deg/min'\n")
    est = estimate(rows, mcap_provenance(paths[-1]), pinned)
    f = next(f for f in est.findings if f.check == "gain")
    assert abs(f.value / GAIN - 1) < 0.01 and not f.applied and f.fix.startswith("pinned")
    assert est.calibration.stw_gain == 1.0 and est.calibration.rot_unit == "deg/min"


@pytest.mark.parametrize(
    "toml, key",
    [
        ("[speed_log]\ngain = 6.0\n", "speed_log.gain"),
        ("[speed_log]\nmisalignment_deg = 90\n", "speed_log.misalignment_deg"),
        ("[rate_of_turn]\nunit = 'rad/s'\n", "rate_of_turn.unit"),
        ("[speed_log]\nscale = 1.0\n", "speed_log.scale"),
    ],
)
def test_a_wrong_pin_is_one_clear_error(toml, key):
    from forcemap.host.fuse import calibration

    with pytest.raises(calibration.ConfigError, match=key.replace(".", r"\.")):
        calibration.loads(toml)
