"""host.vessel: the one geodesy (against pyproj's WGS-84 geodesics), the wrap ranges, and the boat's
equations shared by the simulator's truth and the planner's belief."""

from __future__ import annotations

import math

import numpy as np
import pytest
from forcemap.host.plan.boat_model import BoatModel
from forcemap.host.vessel import geodesy as g
from forcemap.host.vessel.boat import Boat, HullState
from forcemap.sim_devices.jetyak import JETYAK
from pyproj import Geod

WGS84 = Geod(ellps="WGS84")


@pytest.mark.parametrize("lat0", [0.0, 33.99, 51.5, 70.0])
def test_local_frame_is_wgs84_metres(lat0):
    """Over a survey's 2 km: along east or north the geodesic's distance to 1 cm; diagonally within
    2e-4 of it (the meridians converge; the projection keeps them parallel: 0.30 m at 70 deg)."""
    f = g.LocalFrame(lat0, 10.0)
    for x, y, rel in [(2000.0, 0.0, 5e-6), (0.0, 2000.0, 5e-6), (-1500.0, 1200.0, 2e-4)]:
        lat, lon = f.to_latlon(x, y)
        _, _, dist = WGS84.inv(10.0, lat0, float(lon), float(lat))
        assert dist == pytest.approx(math.hypot(x, y), rel=rel)
        assert np.allclose(f.to_local(lat, lon), (x, y), atol=1e-6)


def test_points_round_trip():
    f = g.LocalFrame(33.99, -81.05)
    xy = np.array([[[0.0, 0.0], [120.5, -33.0]], [[-800.0, 400.0], [5.0, 5.0]]])
    ll = f.points_to_latlon(xy)
    assert ll.shape == xy.shape
    assert np.allclose(f.points_to_local(ll), xy, atol=1e-6)


def test_each_wrap_has_its_range():
    assert g.wrap_to_180(180.0) == 180.0 and g.wrap_to_180(-180.0) == 180.0
    assert g.wrap_to_180(190.0) == pytest.approx(-170.0)
    a = g.wrap_from_minus180(np.array([180.0, -180.0, 190.0, 540.0]))
    assert a.tolist() == [-180.0, -180.0, -170.0, -180.0]
    assert g.wrap_from_minus_pi(math.pi) == pytest.approx(-math.pi)
    assert g.wrap360(-0.0) == 0.0 and g.wrap360(-90.0) == 270.0
    rng = np.random.default_rng(0)
    for d in rng.uniform(-1000, 1000, 200):
        assert -180.0 < g.wrap_to_180(d) <= 180.0
        assert -180.0 <= g.wrap_from_minus180(d) < 180.0
        assert g.wrap_to_180(d) % 360.0 == pytest.approx(float(g.wrap_from_minus180(d)) % 360.0)


def test_top_speed_is_the_equations():
    """`BoatParams.max_speed` is where the integrated hull settles at full throttle (with the air moving
    along with the boat: the hull's drag only)."""
    boat = Boat(JETYAK, HullState())
    for _ in range(int(120 / 0.05)):
        boat.step(0.05, 1.0, 0.0, (0.0, 0.0), (boat.s.ve, boat.s.vn))
    assert boat.s.u == pytest.approx(JETYAK.max_speed, rel=1e-3)


def test_planner_belief_is_its_own():
    """The planner's boat is a value of its own: changing it leaves the simulator's truth alone."""
    m = BoatModel().with_max_speed(4.0)
    assert m.max_speed == pytest.approx(4.0)
    assert JETYAK.max_speed == pytest.approx(BoatModel().max_speed)
    assert JETYAK.max_speed > 5.0
