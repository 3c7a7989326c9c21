import numpy as np
import pytest
from scipy import ndimage

import learning.peaks as peaks_module
from learning.peaks import PeakConfig, find_peaks
from typed_config import ConfigError

NO_CONTRAST = PeakConfig(min_contrast=0.0, threshold_abs=0.1)


def gaussian(shape, x, y, height=1.0, sigma=1.0):
    ys, xs = np.mgrid[0 : shape[0], 0 : shape[1]]
    return height * np.exp(-((xs - x) ** 2 + (ys - y) ** 2) / (2 * sigma**2))


def test_subpixel_refinement_recovers_offset_gaussian_centre():
    u = gaussian((20, 20), 7.3, 12.8, sigma=1.5)
    (peak,) = find_peaks(u)
    assert peak == pytest.approx([7.3, 12.8], abs=0.1)
    (coarse,) = find_peaks(u, PeakConfig(subpixel=False))
    assert coarse.tolist() == [7.0, 13.0]


def test_plateau_gives_one_peak_at_its_centroid():
    u = np.zeros((10, 10))
    u[4:6, 3:6] = 1.0  # a 2 x 3 plateau
    peaks = find_peaks(u, NO_CONTRAST)
    assert peaks.tolist() == [[4.0, 4.5]]


@pytest.mark.parametrize("row,col", [(0, 0), (0, 9), (7, 0), (7, 9), (0, 4)], ids=str)
def test_peak_on_border_is_found_at_its_pixel(row, col):
    u = gaussian((8, 10), col, row)
    peaks = find_peaks(u)
    assert peaks.tolist() == [[float(col), float(row)]]


def test_at_most_k_peaks_by_decreasing_value():
    u = np.zeros((40, 40))
    heights = [0.6, 1.0, 0.9, 0.7, 0.8]
    for i, h in enumerate(heights):
        u += gaussian(u.shape, 5 + 7 * i, 20, height=h)
    peaks = find_peaks(u, max_peaks=3)
    assert peaks[:, 0].round().tolist() == [12.0, 19.0, 33.0]
    assert len(find_peaks(u)) == 5


def test_non_maximum_suppression_keeps_the_higher_of_two_close_peaks():
    u = np.zeros((12, 12))
    u[5, 5], u[5, 7] = 1.0, 0.9
    assert find_peaks(u, PeakConfig(min_distance_px=2, subpixel=False)).tolist() == [[5.0, 5.0]]
    assert len(find_peaks(u, PeakConfig(min_distance_px=1, subpixel=False))) == 2


def test_threshold_and_contrast_reject_weak_or_flat_maxima():
    u = gaussian((30, 30), 8, 8, height=0.3) + gaussian((30, 30), 20, 20, height=1.0)
    assert len(find_peaks(u, PeakConfig(threshold_abs=0.5))) == 1
    broad = 2.0 + gaussian((30, 30), 15, 15, height=0.05, sigma=8.0)  # a high but flat maximum
    assert len(find_peaks(broad, PeakConfig(threshold_abs=0.5, min_contrast=0.25))) == 0
    assert len(find_peaks(broad, PeakConfig(threshold_abs=0.5, min_contrast=0.0))) == 1


def test_flat_and_empty_maps_have_no_peaks():
    assert find_peaks(np.zeros((16, 16))).shape == (0, 2)
    assert find_peaks(np.ones((16, 16)), PeakConfig(min_contrast=0.0)).shape == (1, 2)
    assert find_peaks(np.ones((16, 16))).shape == (0, 2)


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="2-D"):
        find_peaks(np.zeros((2, 3, 4)))
    with pytest.raises(ValueError, match="finite"):
        find_peaks(np.full((4, 4), np.nan))


@pytest.mark.parametrize("config", [
    PeakConfig(),
    PeakConfig(threshold_abs=0.05, min_contrast=0.0),
    PeakConfig(threshold_abs=0.3, min_contrast=0.02, min_distance_px=3),
    PeakConfig(threshold_abs=0.1, subpixel=False, max_peaks=4),
])
def test_the_fast_path_for_maps_without_plateaus_equals_the_labelled_path(config, monkeypatch):
    rng = np.random.default_rng(5)
    maps = [ndimage.gaussian_filter(rng.random((64, 64)), sigma=rng.uniform(0.7, 3.0)) * 3 for _ in range(60)]
    seen: list[bool] = []
    has_plateau = peaks_module._has_plateau
    monkeypatch.setattr(peaks_module, "_has_plateau", lambda c: seen.append(has_plateau(c)) or seen[-1])
    fast = [find_peaks(u, config) for u in maps]
    assert seen and not any(seen)  # every map took the fast path
    assert sum(len(p) for p in fast) > 60  # and the maps do have peaks
    monkeypatch.setattr(peaks_module, "_has_plateau", lambda candidates: True)  # always label regions
    for u, expected in zip(maps, fast, strict=True):
        assert np.array_equal(find_peaks(u, config), expected)


def test_plateaus_are_detected_in_all_four_directions():
    for a, b in [((3, 3), (3, 4)), ((3, 3), (4, 3)), ((3, 3), (4, 4)), ((3, 4), (4, 3))]:
        candidates = np.zeros((8, 8), dtype=bool)
        candidates[a] = candidates[b] = True
        assert peaks_module._has_plateau(candidates)
    apart = np.zeros((8, 8), dtype=bool)
    apart[1, 1] = apart[1, 3] = apart[3, 1] = True
    assert not peaks_module._has_plateau(apart)


def test_a_noisy_64px_map_gives_the_full_budget_of_separated_peaks():
    peaks = find_peaks(np.random.default_rng(0).random((64, 64)))
    assert len(peaks) == 10
    gaps = np.hypot(*(peaks[:, None, :] - peaks[None, :, :]).transpose(2, 0, 1))
    assert gaps[~np.eye(10, dtype=bool)].min() >= PeakConfig().min_distance_px


def _building(shape, cols):
    """A raster whose first channel is 1 on the columns ``cols`` (the building), 0 elsewhere."""
    raster = np.zeros((2, *shape))
    raster[0][:, cols] = 1.0
    return raster


@pytest.mark.parametrize("region,expected_col", [("filled", 4.0), ("empty", 5.0)])
def test_a_peak_across_the_wall_moves_to_the_best_allowed_pixel(region, expected_col):
    u = gaussian((9, 12), 4.4, 4.0)  # the maximum at column 4, inside; column 5 is the best outside
    raster = _building((9, 12), slice(0, 5))
    (peak,) = find_peaks(u, PeakConfig(region=region, threshold_abs=0.1, min_contrast=0.0), raster=raster)
    assert np.rint(peak).tolist() == [expected_col, 4.0]
    allowed = peaks_module.allowed_pixels(raster, region)
    assert allowed[int(np.rint(peak[1])), int(np.rint(peak[0]))]


def test_a_disallowed_maximum_does_not_suppress_an_allowed_peak_beside_it():
    u = gaussian((9, 12), 5.0, 4.0, height=1.0) + gaussian((9, 12), 3.0, 4.0, height=0.6)
    raster = _building((9, 12), slice(0, 4))
    config = PeakConfig(threshold_abs=0.3, min_contrast=0.0, min_distance_px=2)
    assert len(find_peaks(u, config)) == 1  # without the region, the wall's peak takes the window
    (peak,) = find_peaks(u, config.replace(region="filled"), raster=raster)
    assert np.rint(peak).tolist() == [3.0, 4.0]


def test_a_plateau_centroid_off_the_region_moves_onto_it():
    u = np.zeros((9, 9))
    u[2:7, 2] = u[2, 2:7] = 1.0  # an L-shaped plateau whose centroid is off the L
    raster = np.zeros((2, 9, 9))
    raster[0] = u
    (peak,) = find_peaks(u, NO_CONTRAST.replace(region="filled"), raster=raster)
    assert raster[0][int(np.rint(peak[1])), int(np.rint(peak[0]))] == 1.0


def test_a_region_without_its_raster_or_of_an_unknown_name_is_refused():
    with pytest.raises(ValueError, match="raster"):
        find_peaks(gaussian((8, 8), 3, 3), PeakConfig(region="empty"))
    with pytest.raises(ValueError, match="raster"):
        find_peaks(gaussian((8, 8), 3, 3), PeakConfig(region="empty"), raster=np.zeros((2, 4, 4)))
    with pytest.raises(ConfigError, match="region"):
        PeakConfig(region="inside")
