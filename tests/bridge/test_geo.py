import numpy as np
import pymap3d
import pytest

from bridge.geo import Home, enu_to_geodetic, enu_to_geodetic_many, geodetic_to_enu
from typed_config import ConfigError

HOME = Home(lat_deg=47.3977418, lon_deg=8.5455938, alt_m=488.0)


@pytest.mark.parametrize("point_m", [(0.0, 0.0, 0.0), (100.0, -250.0, 30.0), (-499.5, 499.5, 120.0)])
def test_enu_geodetic_round_trip(point_m):
    back_m = geodetic_to_enu(HOME, *enu_to_geodetic(HOME, *point_m))
    assert back_m == pytest.approx(point_m, abs=1e-6)


def test_north_offset_matches_pymap3d_and_meridian_arc():
    lat_deg, lon_deg, alt_m = enu_to_geodetic(HOME, 0.0, 1000.0, 0.0)
    assert lon_deg == pytest.approx(HOME.lon_deg, abs=1e-9)
    # one degree of latitude near 47 N is about 111.2 km
    assert (lat_deg - HOME.lat_deg) * 111_200 == pytest.approx(1000.0, rel=2e-3)
    expected = pymap3d.enu2geodetic(0.0, 1000.0, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_m)
    assert (lat_deg, lon_deg, alt_m) == pytest.approx(tuple(float(v) for v in expected))


def test_home_rejects_out_of_range_latitude():
    with pytest.raises(ConfigError, match="lat_deg = 91.0 is out of range"):
        Home(lat_deg=91.0, lon_deg=0.0, alt_m=0.0)


def test_many_points_convert_as_each_one_does():
    home = Home(lat_deg=-35.363262, lon_deg=149.165237, alt_m=584.0)
    points = np.random.default_rng(3).uniform(-2000.0, 2000.0, (50, 3))
    one_by_one = np.array([enu_to_geodetic(home, *p) for p in points])
    np.testing.assert_array_equal(enu_to_geodetic_many(home, points), one_by_one)
    assert enu_to_geodetic_many(home, np.empty((0, 3))).shape == (0, 3)
