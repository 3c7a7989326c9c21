"""Drawing of frames: layers land where the world puts them."""

import numpy as np

from uav_swarm.env.render import draw_frame


def _frame(**overrides):
    kwargs = {
        "obstacles_m": np.array([[10.0, 40.0, 90.0, 40.0]]),
        "pedestrians_m": np.array([[20.0, 10.0], [80.0, 10.0]]),
        "covered": np.array([True, False]),
        "uavs_m": np.array([[20.0, 15.0]]),
        "coverage_radius_m": 12.0,
        "width_px": 200,
    }
    return draw_frame(100.0, 50.0, **{**kwargs, **overrides})


def test_shape_keeps_aspect_ratio():
    frame = _frame()
    assert frame.shape == (100, 200, 3) and frame.dtype == np.uint8


def test_layers_are_drawn_north_up():
    frame = _frame()
    # y = 40 m -> row (50 - 40) * 2 = 20: the obstacle is black there, between x = 10 and 90 m.
    assert frame[20, 100].tolist() == [20, 20, 20]
    # The covered pedestrian (20, 10) m -> (col 40, row 80) is green; the other, outside any disc, grey.
    assert frame[80, 40].tolist() == [30, 150, 60]
    assert frame[80, 160].tolist() == [150, 150, 150]
    # The UAV at (20, 15) m -> (col 40, row 70) is red; its disc tints the background blue-ish.
    assert frame[70, 40].tolist() == [220, 30, 30]
    disc = frame[70, 58]
    assert disc[2] > disc[0] and disc.tolist() != [255, 255, 255]
    assert frame[5, 190].tolist() == [255, 255, 255]


def test_no_disc_and_empty_crowd():
    frame = _frame(coverage_radius_m=0.0, pedestrians_m=np.zeros((0, 2)), covered=np.zeros(0, bool))
    assert frame[70, 58].tolist() == [255, 255, 255]
    assert frame[80, 160].tolist() == [255, 255, 255]
