"""boat.toml: defaults, the shipped example, and one clear error naming the key for bad input."""

from __future__ import annotations

import pytest
from forcemap.host.fuse.calibration import Calibration, ConfigError, example_path, load, loads


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
    ("[anemometer]\nmps_per_hz = -1\n", "anemometer.mps_per_hz: -1 is outside the plausible range"),
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


WRONG_UNITS = [
    # km/h per Hz where m/s per Hz is asked
    ("[anemometer]\nmps_per_hz = 2.4\n", "anemometer.mps_per_hz: 2.4", "0.1 to 2 m/s per Hz"),
    ("[anemometer]\nmps_per_hz = 0.05\n", "anemometer.mps_per_hz: 0.05", "0.1 to 2 m/s per Hz"),
    # millivolts where volts are asked
    ("[vane]\nvref = 3300\n", "vane.vref: 3300", "1 to 5.5 V"),
    ("[vane]\nadc_ref = 0.5\n", "vane.adc_ref: 0.5", "1 to 5.5 V"),
    ("[vane]\npullup_ohm = 10\n", "vane.pullup_ohm: 10", "100 to 1e+06 ohm"),
    (
        "[[wheels]]\npulses_per_m = 20000\n[[wheels]]\n[[wheels]]\n[[wheels]]\n",
        "wheels[0].pulses_per_m: 20000",
        "0.5 to 500",
    ),
    # the default axes (45, 135, -135, -45) in radians
    (
        "".join(f"[[wheels]]\nangle_deg = {a}\n" for a in (0.785, 2.356, -2.356, -0.785)),
        "0.785, 2.356, -2.356, -0.785 look like radians",
        "degrees clockwise from the bow",
    ),
]


@pytest.mark.parametrize(("text", "key", "hint"), WRONG_UNITS)
def test_wrong_units_are_refused_with_the_plausible_range(text, key, hint):
    with pytest.raises(ConfigError) as e:
        loads(text, source="boat.toml")
    msg = str(e.value)
    assert key in msg and hint in msg and "\n" not in msg


def test_plausible_edges_are_accepted():
    cal = loads("[anemometer]\nmps_per_hz = 2.0\n[vane]\nvref = 5.0\nadc_ref = 1.0\n")
    assert (cal.anemo_mps_per_hz, cal.vane_vref, cal.vane_adc_ref) == (2.0, 5.0, 1.0)
    # one wheel on the bow axis is fine: radians are recognised only when all four are within 2 pi
    cal = loads("".join(f"[[wheels]]\nangle_deg = {a}\n" for a in (0, 90, 180, -90)))
    assert [w.angle_deg for w in cal.wheels] == [0.0, 90.0, 180.0, -90.0]


def test_calibration_error_is_one_line_from_the_cli(tmp_path, capsys):
    from forcemap.host.cli import main

    boat = tmp_path / "boat.toml"
    boat.write_text("[vane]\nvref = 3300\n")
    code = main(
        ["run", "--boat", str(boat), "--bridge", str(tmp_path / "none"), "-o", str(tmp_path)]
    )
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert "vane.vref: 3300 is outside the plausible range 1 to 5.5 V" in err
