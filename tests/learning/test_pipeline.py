"""Tiny-budget end to end: dataset (16 scenes) -> train (2 steps) -> evaluate, all under tmp_path."""

import json

import numpy as np
import pytest
from blob_task import BlobTask, make_blob_task

from learning.checkpoint import load_checkpoint
from learning.data import generate_dataset
from learning.evaluate import evaluate
from learning.inference import predict_positions, utility_map
from learning.metrics import aggregate, score_sample
from learning.model import ModelConfig
from learning.train import TrainConfig, train


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    root = tmp_path_factory.mktemp("pipeline")
    generate_dataset(make_blob_task, 16, 0, root / "data", shard_size=8, workers=1, progress=False)
    result = train(root / "data", root / "run", model_config=ModelConfig(arch="unet", width=4, depth=2),
                   train_config=TrainConfig(max_steps=2, batch_size=4, device="cpu"), progress=False)
    return root, result


def test_evaluate_writes_recomputable_results(trained):
    root, result = trained
    summary = evaluate(result.checkpoint, make_blob_task, 8, 0, root / "eval", workers=1, n_examples=2,
                       progress=False)
    out = root / "eval"
    results = json.loads((out / "results.json").read_text())
    assert len(results["samples"]) == 8
    scores = [score_sample(np.array(s["expert"]).reshape(-1, 2), np.array(s["predicted"]).reshape(-1, 2),
                           results["eps_px"]) for s in results["samples"]]
    recomputed = aggregate(scores)
    assert recomputed["corr"] == pytest.approx(summary["corr"])
    assert recomputed["precision"] == pytest.approx(summary["precision"])
    assert summary["expert_qos"] == 1.0 and 0.0 <= summary["qos"] <= 1.0
    assert json.loads((out / "summary.json").read_text())["n_samples"] == 8
    assert (out / "results.md").read_text().startswith("| Task | Corr %")
    assert (out / "examples.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_evaluation_refuses_training_scenes(trained):
    root, result = trained
    with pytest.raises(ValueError, match="training dataset"):
        evaluate(result.checkpoint, make_blob_task, 4, 0, root / "leak", split="train", workers=1,
                 n_examples=0, progress=False)


def test_predict_positions_for_the_planner(trained):
    _, result = trained
    ckpt = load_checkpoint(result.checkpoint)
    task = BlobTask()
    raster = task.observe(task.sample(np.random.default_rng(5)))
    assert utility_map(ckpt.model, raster).shape == (32, 32)
    positions = predict_positions(ckpt.model, raster, k=3, peaks=ckpt.peak_config.replace(threshold_abs=-1e9,
                                                                                          min_contrast=0.0))
    assert positions.shape[1] == 2 and 1 <= len(positions) <= 3
    with pytest.raises(ValueError, match="raster shape"):
        predict_positions(ckpt.model, raster[0], k=3)
