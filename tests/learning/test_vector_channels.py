"""Vector channels turn with the raster: augmentation, TTA and the velocity raster agree."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from learning.inference import apply_symmetry, utility_maps
from learning.model import ModelConfig, UtilityNet
from learning.symmetry import SYMMETRIES, transform_vector_channels
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask, crowd_raster

VELOCITY = WifiTask(WifiConfig(strategy=2, velocity_channels=True))


def raster_transform(x, symmetry):
    flip_x, flip_y, transpose = symmetry
    x = x[:, :, ::-1] if flip_x else x
    x = x[:, ::-1, :] if flip_y else x
    return x.transpose(0, 2, 1) if transpose else x


def test_the_velocity_raster_sums_each_pixels_velocities():
    users = np.array([[10.0, 10.0], [11.0, 11.0], [150.0, 50.0]])
    vels = np.array([[1.0, -2.0], [0.5, 0.0], [0.0, 3.0]])
    raster = crowd_raster(users, VELOCITY.config, vels)
    scale = VELOCITY.config.density_scale
    assert raster.shape == (3, 64, 64) and VELOCITY.channels == 3 and VELOCITY.vector_channels == (1, 2)
    np.testing.assert_allclose(raster[1].sum() * scale, 1.5, rtol=1e-6)
    np.testing.assert_allclose(raster[2].sum() * scale, 1.0, rtol=1e-6)
    with pytest.raises(ValueError, match="velocities"):
        crowd_raster(users, VELOCITY.config)


@pytest.mark.parametrize("symmetry", SYMMETRIES[1:], ids=str)
def test_a_turned_raster_is_the_raster_of_the_turned_crowd(symmetry):
    scene = VELOCITY.sample(np.random.default_rng(5))
    moved = raster_transform(VELOCITY.observe(scene), symmetry)
    turned = transform_vector_channels(moved, (1, 2), *symmetry)
    expected = VELOCITY.observe(VELOCITY.transform_scene(scene, *symmetry))
    np.testing.assert_allclose(turned, expected, atol=1e-5)


def test_numpy_and_torch_turn_alike_and_inputs_stay_untouched():
    x = np.random.default_rng(0).normal(size=(2, 3, 4, 4)).astype(np.float32)
    before = x.copy()
    for symmetry in SYMMETRIES:
        a = transform_vector_channels(x, (1, 2), *symmetry)
        b = transform_vector_channels(torch.from_numpy(x), (1, 2), *symmetry).numpy()
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(x, before)
    assert transform_vector_channels(x, (), True, True, True) is x
    with pytest.raises(ValueError, match="pairs"):
        transform_vector_channels(x, (1,), True, False, False)


def test_test_time_augmentation_turns_the_vector_channels():
    torch.manual_seed(0)
    config = ModelConfig(arch="unet", width=4, depth=2, in_channels=3, vector_channels=(1, 2))
    model = UtilityNet(config).eval()
    scene = VELOCITY.sample(np.random.default_rng(6))
    x = VELOCITY.observe(scene)[None]
    maps = utility_maps(model, x, tta=True)
    flip = SYMMETRIES[5]
    turned = VELOCITY.observe(VELOCITY.transform_scene(scene, *flip))[None]
    expected = apply_symmetry(torch.from_numpy(maps), *flip).numpy()
    # the TTA map of the turned crowd is the turned TTA map: the 8 views are the same set
    np.testing.assert_allclose(utility_maps(model, turned, tta=True), expected, atol=1e-5)
