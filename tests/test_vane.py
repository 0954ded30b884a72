"""Host vane decoding: every resistor position at 3.3 V decodes to its direction."""

import pytest
from forcemap.host.decode import vane
from forcemap.host.vessel.geodesy import wrap_to_180
from forcemap.sim_devices.bridge_emu import vane_voltage

# ideal read_u16 values at 3.3 V with a 10 kOhm pull-up (research notes; the SparkFun library's constants)
IDEAL = [
    50294,
    25985,
    29527,
    5361,
    5958,
    4219,
    11818,
    8099,
    18388,
    15661,
    40329,
    38365,
    60494,
    52961,
    56785,
    44978,
]


def test_ideal_table_matches_research():
    assert [vane.ideal_raw(r) for _, r in vane.DEFAULT_TABLE] == IDEAL


def test_odd_positions_are_adjacent_pairs_in_parallel():
    t = vane.DEFAULT_TABLE
    for i in range(1, 16, 2):
        a, b = t[i - 1][1], t[(i + 1) % 16][1]
        assert t[i][1] == pytest.approx(a * b / (a + b), rel=0.005)


@pytest.mark.parametrize("i", range(16))
def test_each_position_decodes(i):
    deg = i * 22.5
    assert vane.decode_vane(IDEAL[i]) == wrap_to_180(deg)
    # the worst case inside the position's band: half the smallest gap to a neighbour, minus one
    for off in (-297, 297):
        assert vane.decode_vane(IDEAL[i] + off) == wrap_to_180(deg)


@pytest.mark.parametrize("i", range(16))
def test_emulated_vane_voltage_through_emulated_adc_decodes(i):
    from forcemap.sim_devices.machine_emu import ADC, VirtualClock

    adc = ADC(VirtualClock(), seed=i, noise_v=0.003)
    adc.set_voltage(vane_voltage(i * 22.5))
    for _ in range(20):
        assert vane.decode_vane(adc.read_u16()) == wrap_to_180(i * 22.5)


def test_rejects_open_and_short_circuit():
    d = vane.VaneDecoder()
    assert d.decode(65535) is None
    assert d.decode(0) is None
    assert d.rejected == 2
    # between 180 and 22.5 deg, far from both
    assert d.decode((18388 + 25985) // 2) is None


def test_mounting_offset_and_range():
    assert vane.decode_vane(IDEAL[8], mounting_offset=0) == 180.0
    assert vane.decode_vane(IDEAL[12]) == -90.0
    assert vane.decode_vane(IDEAL[0], mounting_offset=-45) == -45.0
    assert vane.decode_vane(IDEAL[12], mounting_offset=90) == 0.0


def test_other_supply_and_pullup():
    raw = vane.ideal_raw(3900, vref=3.3, pullup=4_700.0)
    assert vane.decode_vane(raw, pullup=4_700.0) == 180.0
    assert vane.decode_vane(raw) != 180.0
