"""Soundings a hydrographer would accept (issue 37), the parts on their own: the tilted beam's geometry and
its correction, each sounding's TVU against IHO S-44, the hull's attitude from XDR, the boat file's
[sounder], a surface that keeps the depth most soundings support, and sounder against sounder."""

from __future__ import annotations

import math

import numpy as np
import pytest
from forcemap.host.decode.nmea import NmeaParser
from forcemap.host.fuse import attitude, sounders, tvu
from forcemap.host.fuse.calibration import ConfigError, loads
from forcemap.host.workbench.depth import surface as depth_surface
from forcemap.host.workbench.diagnose.catalogue import explain
from forcemap.host.workbench.survey.instruments import Instruments

from tests.test_daemon_support import nmea_line


@pytest.mark.parametrize("beam", [6.0, 10.0, 20.0])
def test_a_tilted_beam_reads_long_only_beyond_half_its_angle_and_the_correction_undoes_it(beam):
    d = 20.0
    for tilt in np.linspace(0.0, 30.0, 61):
        read = attitude.reading_over_slope(d, tilt, 0.0, beam)
        if tilt <= beam / 2:
            assert read == pytest.approx(d)  # the vertical is inside the cone: the slant is hidden
        else:
            assert read == pytest.approx(d / math.cos(math.radians(tilt - beam / 2)))
        # over a flat bed the correction gives the depth back, whichever way the hull leans
        roll, pitch = (
            tilt * 0.8,
            math.degrees(
                math.acos(math.cos(math.radians(tilt)) / math.cos(math.radians(tilt * 0.8)))
            ),
        )
        fixed = attitude.corrected(
            np.array([read + 0.3]), 0.3, np.array([roll]), np.array([pitch]), beam
        )
        assert fixed[0] == pytest.approx(d + 0.3, abs=1e-9)


def test_on_a_sloping_bed_the_nearest_point_lies_along_its_normal():
    d, slope = 30.0, 12.0
    # upright, a beam wider than the slope sees the bed's normal: it reads short, D cos s
    assert attitude.reading_over_slope(d, 0.0, slope, 30.0) == pytest.approx(
        d * math.cos(math.radians(slope))
    )
    # a narrow beam upright reads along its edge nearest the normal
    narrow = attitude.reading_over_slope(d, 0.0, slope, 10.0)
    assert narrow == pytest.approx(
        d * math.cos(math.radians(slope)) / math.cos(math.radians(slope - 5.0))
    )
    # leaning down the slope reads longer than leaning up it by the same angle
    down = attitude.reading_over_slope(d, 15.0, slope, 10.0, toward=0.0)
    up = attitude.reading_over_slope(d, 15.0, slope, 10.0, toward=180.0)
    assert down > d > up
    # with no attitude the sounding stays as read, and the tilt's uncertainty is zero
    nan = np.array([np.nan])
    assert attitude.corrected(np.array([d]), 0.0, nan, nan, 10.0)[0] == d
    assert attitude.correction_sd(np.array([d]), 0.0, nan, nan, 10.0)[0] == 0.0


def test_s44_orders_and_a_soundings_tvu():
    # S-44 6th ed.: Special a = 0.25 m, b = 0.0075; Order 1a/1b a = 0.5 m, b = 0.013
    assert tvu.allowed(np.array([10.0]), "special")[0] == pytest.approx(math.hypot(0.25, 0.075))
    assert tvu.allowed(np.array([40.0]), "1a/1b")[0] == pytest.approx(math.hypot(0.5, 0.52))
    depth = np.array([10.0, 10.0, 10.0, 10.0, np.nan])
    u = np.array([0.1, 0.26, 0.5, 5.0, 0.1])
    assert tvu.order_met(u, depth).tolist() == [1, 2, 3, 0, -1]  # exclusive, special, 1a/1b, none
    assert tvu.meets(u, depth, "1a/1b").tolist() == [True, True, True, False, False]
    # the terms add in quadrature and scale to 95 %
    spec = tvu.SounderSpec(0.1, 0.0)
    one = tvu.sounding_tvu(np.array([10.0, 10.1]), spec, 0.2, 0.1, 2.0, 0.05)
    sd = math.sqrt(0.1**2 + (0.1 / math.sqrt(12)) ** 2 + 0.2**2 + 0.2**2 + 0.05**2)
    assert one.tvu[0] == pytest.approx(1.96 * sd)
    assert set(one.largest()) <= {"attitude", "position"}


def test_the_hulls_attitude_from_xdr_as_real_logs_send_it():
    p = NmeaParser()
    bg = p.parse(b"$IIXDR,C,,C,AIRTEMP,A,-1.0,D,HEEL,A,2.9,D,TRIM,P,,B,BARO,A,-3.9,D,RUDDER*29")
    assert bg.valid and bg.data == {"roll": -1.0, "pitch": 2.9}  # bundg_zeus_9.log, B&G Zeus
    nmea4 = p.parse(nmea_line("YXXDR,A,-4.5,D,PTCH,A,12.1,D,ROLL"))
    assert nmea4.data == {"roll": 12.1, "pitch": -4.5}
    other = p.parse(nmea_line("IIXDR,C,21.5,C,AIRTEMP"))
    assert other.valid and other.data == {"roll": None, "pitch": None}


def test_the_boat_files_sounder():
    cal = loads("[sounder]\nbeam_angle_deg = 10\naccuracy_m = 0.05\naccuracy_share = 0.002\n")
    assert (cal.sounder_beam_deg, cal.sounder_accuracy_m, cal.sounder_accuracy_share) == (
        10,
        0.05,
        0.002,
    )
    with pytest.raises(ConfigError, match="sounder.beam_angle_deg: expected at most 90"):
        loads("[sounder]\nbeam_angle_deg = 120\n")
    with pytest.raises(ConfigError, match="sounder.beam: unknown key"):
        loads("[sounder]\nbeam = 10\n")


def _plane(n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    xy = rng.uniform(0.0, 40.0, (n, 2))
    return xy, 20.0 + 0.05 * xy[:, 0] + 0.03 * rng.standard_normal(n)


def test_the_surface_keeps_the_depth_most_soundings_support():
    """A second return 6 m above the bed in a third of the soundings of one patch: the surface keeps
    the bed there, with two hypotheses; cells no sounding reaches stay empty."""
    rng = np.random.default_rng(3)
    xy, z = _plane(3000, rng)
    patch = (xy[:, 0] < 15) & (xy[:, 1] < 15) & (rng.random(3000) < 0.33)
    z[patch] -= 6.0
    s = {"xy": xy, "depth": z, "sd": np.full(3000, 0.1), "slope": np.full(3000, 0.05),
         "t": np.arange(3000.0), "position_sd": 1.0}  # fmt: skip
    gx, gy = np.meshgrid(np.arange(2.5, 60.0, 5.0), np.arange(2.5, 40.0, 5.0))
    nodes = np.column_stack([gx.ravel(), gy.ravel()])
    surf = depth_surface.build(nodes, s, 5.0)
    reach = np.min(np.hypot(*(nodes[:, None, :] - xy[None, :, :]).transpose(2, 0, 1)), axis=1)
    inside = reach <= depth_surface.CAPTURE * 5.0
    bed = 20.0 + 0.05 * nodes[:, 0]
    interior = nodes[:, 0] < 40  # at the edge a node takes soundings from one side: slope x reach
    assert np.all(np.abs(surf.depth[interior] - bed[interior]) < 0.15)
    assert np.all(np.abs(surf.depth[inside] - bed[inside]) < 0.05 * depth_surface.CAPTURE * 5.0)
    assert np.all(np.isnan(surf.depth[~inside])) and np.all(surf.soundings[~inside] == 0)
    in_patch = inside & (nodes[:, 0] < 12) & (nodes[:, 1] < 12)
    assert np.all(surf.hypotheses[in_patch] >= 2) and np.all(surf.support[in_patch] > 0.5)
    # a 0.1 m sd sounder at 20 m on a 1-in-20 slope meets Order 1a/1b (S-44: in 95 % of the cells);
    # one of 0.5 m does not
    def order1(o: np.ndarray) -> np.ndarray:
        return (o >= 1) & (o <= tvu.ORDER_CODES["1a/1b"])

    assert np.mean(order1(surf.order()[interior])) >= 0.95
    worse = depth_surface.build(nodes, {**s, "sd": np.full(3000, 0.5)}, 5.0)
    assert np.mean(order1(worse.order()[interior])) <= 0.05


def test_sounder_against_sounder_trusts_the_one_on_a_seabed():
    """Two transducers over one bed, the second 0.4 m shallower (mounted higher) and losing the bottom
    for two minutes: their offset, the stretch they disagree in, and the first trusted."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 1200.0)
    bed = 30.0 + 5.0 * np.sin(t / 200.0)
    a = bed + 0.05 * rng.standard_normal(len(t))
    b = bed - 0.4 + 0.05 * rng.standard_normal(len(t))
    b[600:720] = rng.uniform(3.0, 28.0, 120)
    (cmp,) = sounders.compare({"nmea SDDPT": (t, a), "nmea YDDPT": (t + 0.3, b)}, "nmea SDDPT")
    assert cmp.offset_m == pytest.approx(-0.4, abs=0.05)
    assert cmp.trusted == "nmea SDDPT" and "seabed" in cmp.why
    ((t0, t1),) = cmp.stretches
    assert abs(t0 - 600) <= 2 and abs(t1 - 719) <= 2
    assert 0.08 < cmp.disagree_share < 0.12


def test_depth_that_follows_the_heading_is_heel_not_a_misaligned_sensor():
    without = explain("heading", Instruments({"depth", "heading", "app_wind_angle"}), "depth")[0]
    assert without.startswith("heel:") and "log the hull's roll and pitch" in without
    assert "misaligned or shadowed" not in without
    with_att = explain("app_wind_angle", Instruments({"depth", "roll", "pitch"}), "depth")[0]
    assert "beam_angle_deg" in with_att and not with_att.startswith("heel:")
    # other targets keep their own causes
    assert "misaligned" in explain("heading", Instruments({"current_speed"}), "current")[0]
