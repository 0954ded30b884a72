"""boat.toml: defaults, the shipped example, and one clear error naming the key for bad input."""

from __future__ import annotations

import pytest
from forcemap.host.calibration import Calibration, ConfigError, example_path, load, loads


def test_defaults_are_the_documented_ones():
    cal = Calibration()
    assert cal.anemo_mps_per_hz == pytest.approx(0.6667)
    assert [w.angle_deg for w in cal.wheels] == [45.0, 135.0, -135.0, -45.0]
    assert cal.vane_vref == 3.3 and cal.vane_pullup_ohm == 10_000.0 and cal.vane_offset_deg == 0.0
    assert len(cal.vane_table) == 16 and cal.vane_table[0] == (0.0, 33_000.0)
    assert cal.sync == "interpolate" and cal.current_estimator == "lsq"
    assert cal.depth_offset_m == 0.0 and cal.magnetic_variation_deg is None


def test_example_file_is_the_defaults():
    assert load(example_path()) == Calibration()
    assert load(None) == Calibration()


def test_values_are_read():
    cal = loads(
        """
        [anemometer]
        mps_per_hz = 0.7
        [vane]
        offset_deg = -12.5
        [[wheels]]
        angle_deg = 40
        pulses_per_m = 9.5
        [[wheels]]
        [[wheels]]
        [[wheels]]
        angle_deg = -50
        [current]
        estimator = "paper"
        min_speed_mps = 0.1
        [depth]
        offset_m = 0.35
        [compass]
        variation_deg = -3.5
        [sync]
        mode = "approximate"
        """
    )
    assert cal.anemo_mps_per_hz == 0.7 and cal.vane_offset_deg == -12.5
    assert [(w.pulses_per_m, w.angle_deg) for w in cal.wheels] == [
        (9.5, 40.0),
        (10.8, 135.0),
        (10.8, -135.0),
        (10.8, -50.0),
    ]
    assert cal.current_estimator == "paper" and cal.wheel_min_speed == 0.1
    assert cal.depth_offset_m == 0.35 and cal.magnetic_variation_deg == -3.5
    assert cal.sync == "approximate"
    meta = cal.as_metadata()
    assert all(isinstance(k, str) and isinstance(v, str) for k, v in meta.items())


BAD = [
    (
        '[[wheels]]\n[[wheels]]\n[[wheels]]\nangle_deg = "abc"\n[[wheels]]\n',
        'wheels[2].angle_deg: expected a number, got "abc"',
    ),
    ("[anemometer]\nmps_per_hz = -1\n", "anemometer.mps_per_hz: expected a positive number"),
    ("[anemometer]\nmps_per_hz = true\n", "anemometer.mps_per_hz: expected a number"),
    ("[vane]\nresistors_ohm = [1, 2, 3]\n", "vane.resistors_ohm: expected a list of 16"),
    ("[vane]\nresistors_ohm = [" + ", ".join(["1000"] * 15) + ', "x"]\n', "vane.resistors_ohm[15]"),
    ("[[wheels]]\nangle_deg = 45\n", "wheels: expected 4 paddle wheels, got 1"),
    (
        "[[wheels]]\nangle_deg = 200\n[[wheels]]\n[[wheels]]\n[[wheels]]\n",
        "wheels[0].angle_deg: expected at most 180",
    ),
    (
        "[[wheels]]\npulses_per_m = 0\n[[wheels]]\n[[wheels]]\n[[wheels]]\n",
        "wheels[0].pulses_per_m",
    ),
    ("[[wheels]]\nspeed = 1\n[[wheels]]\n[[wheels]]\n[[wheels]]\n", "wheels[0].speed: unknown key"),
    ('[sync]\nmode = "nearest"\n', "sync.mode: expected one of"),
    ("[current]\nestimator = 3\n", "current.estimator"),
    ('[compass]\nvariation_deg = "east"\n', "compass.variation_deg"),
    ("[depth]\noffset_m = nan\n", "depth.offset_m: expected a finite number"),
    ("vane = 3\n", "vane: expected a table"),
    ("[anemometr]\n", "anemometr: unknown key"),
    ("wheels = 4\n", "wheels: expected an array of tables"),
    ("[vane\n", "invalid TOML"),
]


@pytest.mark.parametrize(("text", "expect"), BAD)
def test_bad_config_is_one_clear_error(text, expect):
    with pytest.raises(ConfigError) as e:
        loads(text, source="boat.toml")
    msg = str(e.value)
    assert expect in msg
    assert msg.startswith("boat.toml: ") and "\n" not in msg


def test_unreadable_file(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load(tmp_path / "missing.toml")
    p = tmp_path / "bin.toml"
    p.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ConfigError):
        load(p)
