import numpy as np
import pytest

from learning.targets import TargetConfig, render_peak_heatmap, render_targets
from typed_config import ConfigError


def brute_force(positions, shape, cfg):
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w]
    out = np.zeros(shape)
    for x, y in positions:
        d2 = (xs - x) ** 2 + (ys - y) ** 2
        out += cfg.alpha1 * np.exp(-d2 / (2 * cfg.sigma1**2)) + cfg.alpha2 * np.exp(-d2 / (2 * cfg.sigma2**2))
    return out


def test_isolated_expert_peaks_at_alpha1_plus_alpha2():
    cfg = TargetConfig(alpha2=40.0, sigma2=5.0)
    r = render_targets(np.array([[20.0, 11.0]]), (32, 48), cfg)
    assert r.dtype == np.float32 and r.shape == (32, 48)
    assert r[11, 20] == pytest.approx(255.0 + 40.0)
    assert np.unravel_index(np.argmax(r), r.shape) == (11, 20)


def test_two_gaussian_sum_matches_definition_for_subpixel_positions():
    cfg = TargetConfig(alpha1=255.0, sigma1=1.0, alpha2=30.0, sigma2=7.0)
    positions = np.array([[3.3, 4.7], [10.0, 10.0], [12.5, 2.25]])
    r = render_targets(positions, (16, 20), cfg)
    np.testing.assert_allclose(r, brute_force(positions, (16, 20), cfg), rtol=1e-5, atol=1e-4)


def test_targets_add_up_over_positions():
    cfg = TargetConfig(alpha2=50.0, sigma2=3.0)
    a, b = np.array([[4.0, 4.0]]), np.array([[9.0, 6.0]])
    both = render_targets(np.concatenate([a, b]), (12, 12), cfg)
    np.testing.assert_allclose(both, render_targets(a, (12, 12), cfg) + render_targets(b, (12, 12), cfg),
                               rtol=1e-6)


def test_empty_placement_gives_zero_map():
    r = render_targets(np.zeros((0, 2)), (5, 7), TargetConfig())
    assert r.shape == (5, 7) and not r.any()


def test_alpha2_zero_keeps_only_the_sharp_gaussian():
    r = render_targets(np.array([[2.0, 2.0]]), (5, 5), TargetConfig(alpha2=0.0))
    assert r[2, 2] == pytest.approx(255.0)
    assert r[2, 3] == pytest.approx(255.0 * np.exp(-0.5), rel=1e-6)


def test_negative_sigma_is_rejected_with_field_name():
    with pytest.raises(ConfigError, match="sigma2"):
        TargetConfig(sigma2=-1.0)


def test_peak_heatmap_is_one_on_each_rounded_position_and_the_max_of_the_gaussians() -> None:
    heatmap = render_peak_heatmap(np.array([[2.4, 3.0], [4.0, 3.0], [9.7, -2.0]]), (6, 8), 1.0)
    assert heatmap.shape == (6, 8) and heatmap.dtype == np.float32
    assert heatmap[3, 2] == heatmap[3, 4] == heatmap[0, 7] == 1.0  # rounded, clipped into the raster
    assert np.isclose(heatmap[3, 3], np.exp(-0.5))  # between the two: the larger Gaussian, not the sum
    assert heatmap.max() == 1.0 and heatmap.min() >= 0.0
    assert not render_peak_heatmap(np.zeros((0, 2)), (4, 4), 1.0).any()
