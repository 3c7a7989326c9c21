import functools

import pytest
import torch
from blob_task import BlobConfig, BlobTask

from learning.checkpoint import CheckpointError, load_checkpoint
from learning.data import generate_dataset
from learning.model import ModelConfig, build_model
from learning.train import TrainConfig, train

SMALL = functools.partial(BlobTask, BlobConfig(size_px=16, max_blobs=2))
TINY_MODEL = ModelConfig(arch="paper", width=4)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("data")
    generate_dataset(SMALL, 20, 3, out, shard_size=10, workers=1, progress=False)
    return out


def weights(path):
    return load_checkpoint(path).model.state_dict()


def same_weights(a, b):
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def run(data, out, resume=None, init=None, **changes):
    cfg = TrainConfig(epochs=2, batch_size=8, val_fraction=0.2, device="cpu").replace(**changes)
    return train(data, out, model_config=TINY_MODEL, train_config=cfg, resume=resume, init=init,
                 progress=False)


def test_training_is_deterministic_on_cpu_and_depends_on_the_seed(data, tmp_path):
    a = run(data, tmp_path / "a")
    b = run(data, tmp_path / "b")
    c = run(data, tmp_path / "c", seed=1)
    assert same_weights(weights(a.checkpoint), weights(b.checkpoint))
    assert not same_weights(weights(a.checkpoint), weights(c.checkpoint))
    assert [h["epoch"] for h in a.history] == [0, 1] and a.history[-1]["step"] == 4
    assert {"train_loss", "val_loss", "val_corr", "val_precision"} <= a.history[-1].keys()
    assert (tmp_path / "a" / "history.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_resume_continues_to_the_same_weights(data, tmp_path):
    # (a cosine schedule spans the configured steps, so the interrupted run is emulated with a constant one)
    full = run(data, tmp_path / "full", schedule="constant")
    first = run(data, tmp_path / "part", epochs=1, schedule="constant")
    cfg = TrainConfig(epochs=2, batch_size=8, val_fraction=0.2, device="cpu", schedule="constant")
    resumed = train(data, tmp_path / "part", train_config=cfg, resume=first.checkpoint, progress=False)
    assert len(resumed.history) == 2
    assert same_weights(weights(full.checkpoint), weights(resumed.checkpoint))


def test_max_steps_stops_early_and_checkpoint_carries_its_metadata(data, tmp_path):
    result = run(data, tmp_path, epochs=50, max_steps=3)
    ckpt = load_checkpoint(result.checkpoint, task_name="blobs", input_shape=(1, 16, 16))
    assert ckpt.payload["step"] == 3 and ckpt.model_config == TINY_MODEL
    assert ckpt.task_config == BlobConfig(size_px=16, max_blobs=2).to_dict()
    assert ckpt.payload["data"] == {"seed": 3, "split": "train", "n": 20}
    assert result.best_checkpoint.exists()
    assert "optimizer_state" not in load_checkpoint(result.best_checkpoint).payload  # lean file to ship
    with pytest.raises(CheckpointError, match="optimizer"):
        train(data, tmp_path / "again", resume=result.best_checkpoint, progress=False)
    assert not list(tmp_path.glob(".*.tmp"))  # atomic writes left no temporary file


def test_bad_checkpoints_give_clear_errors(data, tmp_path):
    good = run(data, tmp_path / "run", max_steps=1).checkpoint
    with pytest.raises(CheckpointError, match="not found"):
        load_checkpoint(tmp_path / "missing.pt")
    truncated = tmp_path / "truncated.pt"
    truncated.write_bytes(good.read_bytes()[:500])
    with pytest.raises(CheckpointError, match="corrupt"):
        load_checkpoint(truncated)
    junk = tmp_path / "junk.pt"
    torch.save({"hello": 1}, junk)
    with pytest.raises(CheckpointError, match="not a learning-utility"):
        load_checkpoint(junk)
    with pytest.raises(CheckpointError, match="task 'blobs', not 'wifi-s1'"):
        load_checkpoint(good, task_name="wifi-s1")
    with pytest.raises(CheckpointError, match="shape"):
        load_checkpoint(good, input_shape=(1, 64, 64))
    with pytest.raises(CheckpointError, match="size_px"):
        load_checkpoint(good, task_config=BlobConfig(size_px=32, max_blobs=2).to_dict())
    other = tmp_path / "other-data"
    bigger = functools.partial(BlobTask, BlobConfig(size_px=24))
    generate_dataset(bigger, 4, 0, other, workers=1, progress=False)
    with pytest.raises(CheckpointError, match="differs"):
        train(other, tmp_path / "other", resume=good, progress=False)


UNET = ModelConfig(arch="unet", width=8, depth=3, coord_channels=True)


@pytest.mark.parametrize("cfg", [ModelConfig(), UNET], ids=["paper", "unet-coord"])
def test_models_map_any_raster_to_a_same_size_utility_map(cfg):
    model = build_model(cfg)
    for shape in [(64, 64), (37, 50)]:
        assert model(torch.zeros(2, 1, *shape)).shape == (2, 1, *shape)


def test_paper_network_has_the_papers_layers():
    model = build_model(ModelConfig())
    convs = [m for m in model.modules() if isinstance(m, torch.nn.Conv2d) and m.kernel_size == (3, 3)]
    assert [c.out_channels for c in convs] == [32, 32, 64, 64, 128, 128]
    transposed = [m.out_channels for m in model.modules() if isinstance(m, torch.nn.ConvTranspose2d)]
    assert transposed == [128, 64, 32]


def test_bfloat16_training_is_deterministic_records_its_precision_and_learns(data, tmp_path):
    a = run(data, tmp_path / "a", precision="bfloat16", epochs=4)
    b = run(data, tmp_path / "b", precision="bfloat16", epochs=4)
    f = run(data, tmp_path / "f", precision="float32", epochs=4)
    assert same_weights(weights(a.checkpoint), weights(b.checkpoint))
    assert not same_weights(weights(a.checkpoint), weights(f.checkpoint))
    assert load_checkpoint(a.checkpoint).payload["precision"] == "bfloat16"
    assert load_checkpoint(f.checkpoint).payload["precision"] == "float32"
    assert all(p.dtype == torch.float32 for p in load_checkpoint(a.checkpoint).model.parameters())
    assert a.history[-1]["train_loss"] < a.history[0]["train_loss"]
    assert [h["samples"] for h in a.history] == [16, 32, 48, 64]


def test_patience_stops_when_validation_stops_improving(data, tmp_path):
    # lr 0 never changes the weights, so the score never improves after epoch 0
    result = run(data, tmp_path, epochs=20, patience=2, lr=1e-12, schedule="constant")
    assert [h["epoch"] for h in result.history] == [0, 1, 2]


def test_init_starts_a_new_run_from_a_checkpoints_weights(data, tmp_path):
    first = run(data, tmp_path / "first")
    tuned = run(data, tmp_path / "tuned", epochs=1, lr=1e-12, schedule="constant", init=first.best_checkpoint)
    start, after = weights(first.best_checkpoint), weights(tuned.checkpoint)
    assert all(torch.allclose(start[k], after[k], atol=1e-6) for k in start)  # lr ~0: the weights stay
    assert [h["epoch"] for h in tuned.history] == [0]
    assert load_checkpoint(tuned.checkpoint).payload["init"] == "best.pt"
    scratch = weights(run(data, tmp_path / "scratch", epochs=1, lr=1e-12, schedule="constant").checkpoint)
    assert not same_weights(scratch, after)
    with pytest.raises(ValueError, match="either resume"):
        run(data, tmp_path / "both", resume=first.checkpoint, init=first.best_checkpoint)


def test_a_peak_head_adds_its_focal_loss_and_can_join_a_trained_network(data, tmp_path):
    head = TINY_MODEL.replace(peak_head=True)
    cfg = TrainConfig(epochs=1, batch_size=8, val_fraction=0.2, device="cpu")
    plain = weights(run(data, tmp_path / "plain", epochs=1).checkpoint)
    silent = weights(train(data, tmp_path / "silent", model_config=head, progress=False,
                           train_config=cfg.replace(focal_weight=0.0)).checkpoint)
    focal = weights(train(data, tmp_path / "focal", model_config=head, progress=False,
                          train_config=cfg.replace(focal_weight=1.0)).checkpoint)
    assert set(silent) - set(plain) == {"peak_head.weight", "peak_head.bias"}
    assert all(torch.equal(plain[k], silent[k]) for k in plain)  # weight 0: the shared layers as without
    assert not all(torch.equal(plain[k], focal[k]) for k in plain)  # the focal loss reaches them
    tuned = train(data, tmp_path / "tuned", model_config=head, progress=False,
                  train_config=cfg.replace(lr=1e-12, schedule="constant"),
                  init=tmp_path / "plain" / "best.pt")
    after, start = weights(tuned.checkpoint), weights(tmp_path / "plain" / "best.pt")
    assert load_checkpoint(tuned.checkpoint).model_config.peak_head
    assert all(torch.allclose(start[k], after[k], atol=1e-6) for k in start)  # the trained layers kept
    with pytest.raises(ValueError, match="no peak head"):
        build_model(TINY_MODEL).forward_with_peaks(torch.zeros(1, 1, 16, 16))
