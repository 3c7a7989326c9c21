import functools

import numpy as np
import pytest
from blob_task import BlobConfig, BlobTask

from learning.calibrate import CalibrationConfig, calibrate_peaks
from learning.checkpoint import load_checkpoint
from learning.data import generate_dataset
from learning.model import ModelConfig
from learning.peaks import PeakConfig, find_peaks
from learning.train import TrainConfig, train
from typed_config import ConfigError


def _two_low_peaks() -> tuple[np.ndarray, np.ndarray]:
    u = np.zeros((16, 16))
    u[4, 4], u[11, 11] = 0.3, 0.2
    return u, np.array([[4.0, 4.0], [11.0, 11.0]])


def test_low_peaks_are_missed_by_the_defaults_and_found_after_calibration():
    u, expert = _two_low_peaks()
    assert len(find_peaks(u, PeakConfig())) == 0
    best, summary = calibrate_peaks([u], [expert], eps_px=1.6, base=PeakConfig())
    assert summary["corr"] == 1.0 and summary["precision"] == 1.0
    assert best.threshold_abs <= 0.2 and best.min_distance_px == PeakConfig().min_distance_px
    np.testing.assert_allclose(np.sort(find_peaks(u, best), axis=0), expert)


def test_calibration_rejects_spurious_peaks_and_breaks_ties_to_the_lowest_grid_point():
    u, expert = _two_low_peaks()
    u[8, 1] = 0.1  # a low spurious bump: any threshold above it keeps precision at 1
    best, summary = calibrate_peaks([u], [expert], 1.6, PeakConfig(),
                                    CalibrationConfig(thresholds=(0.05, 0.15, 0.25), contrasts=(0.0, 0.05)))
    assert summary["precision"] == 1.0 and summary["corr"] == 1.0
    assert (best.threshold_abs, best.min_contrast) == (0.15, 0.0)


def test_bad_inputs_and_grids_are_clear_errors():
    u, expert = _two_low_peaks()
    with pytest.raises(ValueError, match="as many utility maps as expert placements"):
        calibrate_peaks([u, u], [expert], 1.6, PeakConfig())
    with pytest.raises(ConfigError, match="must each hold at least one value"):
        CalibrationConfig(thresholds=())
    with pytest.raises(ConfigError, match="must be >= 0"):
        CalibrationConfig(contrasts=(-0.1,))


def test_training_with_calibration_ships_the_chosen_thresholds(tmp_path):
    data = tmp_path / "data"
    generate_dataset(functools.partial(BlobTask, BlobConfig(size_px=16, max_blobs=2)), 20, 3, data,
                     shard_size=10, workers=1, progress=False)
    cfg = TrainConfig(epochs=2, batch_size=8, val_fraction=0.2, device="cpu", calibrate_peaks=True)
    result = train(data, tmp_path / "run", model_config=ModelConfig(arch="paper", width=4), train_config=cfg,
                   progress=False)
    grid = CalibrationConfig()
    for record in result.history:
        assert record["threshold_abs"] in grid.thresholds and record["min_contrast"] in grid.contrasts
    best = load_checkpoint(result.best_checkpoint)
    chosen = [(r["threshold_abs"], r["min_contrast"]) for r in result.history]
    assert (best.peak_config.threshold_abs, best.peak_config.min_contrast) in chosen
    # The resumable checkpoint keeps the configured base settings.
    assert load_checkpoint(result.checkpoint).peak_config == PeakConfig()
