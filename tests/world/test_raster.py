"""Density maps and the metre <-> pixel mapping."""

import numpy as np
import pytest

from uav_swarm.world.raster import density_map, metres_to_pixels, pixels_to_metres


def test_density_counts_every_pedestrian_in_its_pixel():
    rng = np.random.default_rng(0)
    positions = rng.uniform([0, 0], [300, 120], size=(1000, 2))
    dmap = density_map(positions, 300.0, 120.0, (12, 30))
    assert dmap.shape == (12, 30) and dmap.dtype == np.float32
    assert dmap.sum() == 1000
    expected, _, _ = np.histogram2d(positions[:, 1], positions[:, 0], bins=(12, 30),
                                    range=((0, 120), (0, 300)))
    assert np.array_equal(dmap, expected.astype(np.float32))


def test_density_rows_are_y_and_far_edges_count():
    positions = np.array([[0.0, 0.0], [10.0, 10.0], [9.0, 1.0], [-0.1, 5.0], [5.0, 10.5]])
    dmap = density_map(positions, 10.0, 10.0, (2, 5))
    assert dmap.tolist() == [[1, 0, 0, 0, 1], [0, 0, 0, 0, 1]]


def test_pixel_centres():
    centres_m = pixels_to_metres(np.array([[0.0, 0.0], [4.0, 1.0]]), 10.0, 10.0, (2, 5))
    assert centres_m.tolist() == [[1.0, 2.5], [9.0, 7.5]]


def test_metres_pixels_round_trip():
    rng = np.random.default_rng(1)
    xy_m = rng.uniform([0, 0], [250, 90], size=(100, 2))
    xy_px = metres_to_pixels(xy_m, 250.0, 90.0, (64, 48))
    assert np.allclose(pixels_to_metres(xy_px, 250.0, 90.0, (64, 48)), xy_m)
    assert np.all(xy_px >= -0.5) and np.all(xy_px[:, 0] <= 47.5) and np.all(xy_px[:, 1] <= 63.5)


def test_density_peak_is_at_metres_to_pixels_of_the_crowd():
    positions = np.full((7, 2), [123.0, 45.0])
    dmap = density_map(positions, 200.0, 100.0, (50, 40))
    row, col = np.unravel_index(np.argmax(dmap), dmap.shape)
    px = metres_to_pixels(positions[:1], 200.0, 100.0, (50, 40))[0]
    assert (col, row) == (round(px[0]), round(px[1]))


@pytest.mark.parametrize(
    ("args", "match"),
    [((np.zeros((3, 3)), 10.0, 10.0, (4, 4)), "positions_m"),
     ((np.zeros((3, 2)), 0.0, 10.0, (4, 4)), "width_m"),
     ((np.zeros((3, 2)), 10.0, 10.0, (0, 4)), "shape")],
)
def test_bad_input_is_an_error(args, match):
    with pytest.raises(ValueError, match=match):
        density_map(*args)
