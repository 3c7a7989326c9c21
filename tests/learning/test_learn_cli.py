"""The registry and the ``uav-swarm dataset | train | evaluate`` commands, on the synthetic blob task."""

import json

import pytest

from typed_config import ConfigError
from uav_swarm.cli import main
from uav_swarm.missions import registry


@pytest.fixture
def blobs(monkeypatch):
    entry = registry.TaskEntry("blob_task:BlobTask", alpha2=20.0, sigma2=3.0)
    monkeypatch.setitem(registry.TASKS, "blobs", entry)


def test_paper_targets_are_the_defaults():
    expected = {"wifi-s1": (50, 50), "wifi-s2": (30, 30), "agp": (40, 40), "fp": (40, 20)}
    for name, (alpha2, sigma2) in expected.items():
        targets = registry.load_settings(name).targets
        assert (targets.alpha1, targets.sigma1, targets.alpha2, targets.sigma2) == (255, 1, alpha2, sigma2)


def test_settings_file_tables_and_errors(tmp_path):
    path = tmp_path / "s1.toml"
    path.write_text("[targets]\nsigma2 = 12.5\n[model]\narch = 'unet'\n[train]\nepochs = 3\n")
    settings = registry.load_settings("wifi-s1", path)
    assert (settings.targets.alpha2, settings.targets.sigma2) == (50, 12.5)
    assert settings.model.arch == "unet" and settings.train.epochs == 3
    path.write_text("[trian]\nepochs = 3\n")
    with pytest.raises(ConfigError, match="trian"):
        registry.load_settings("wifi-s1", path)
    path.write_text("[train]\nepoch = 3\n")
    with pytest.raises(ConfigError, match=r"\[train\].*epoch"):
        registry.load_settings("wifi-s1", path)
    with pytest.raises(ConfigError, match="wifi-s3"):
        registry.make_task("wifi-s3")
    with pytest.raises(ConfigError, match="strategy"):
        registry.make_task("wifi-s1", overrides={"strategy": 2})


def test_task_factory_rebuilds_the_same_task(blobs):
    task = registry.make_task("blobs", overrides={"size_px": 16})
    again = registry.task_factory(task)()
    assert again.config == task.config and again.shape == (16, 16)


def test_dataset_train_evaluate_commands(blobs, tmp_path, capsys):
    config = tmp_path / "blobs.toml"
    config.write_text("[task]\nsize_px = 16\n[model]\nwidth = 4\n[train]\nbatch_size = 4\ndevice = 'cpu'\n")
    data, run, evaluation = tmp_path / "data", tmp_path / "run", tmp_path / "eval"
    assert main(["dataset", "--task", "blobs", "--config", str(config), "--n", "12", "--seed", "4",
                 "--out", str(data), "--workers", "1"]) == 0
    assert json.loads((data / "manifest.json").read_text())["task_config"]["size_px"] == 16
    assert main(["train", "--task", "blobs", "--config", str(config), "--data", str(data), "--out", str(run),
                 "--max-steps", "2"]) == 0
    assert main(["evaluate", "--task", "blobs", "--checkpoint", str(run / "checkpoint.pt"), "--n", "4",
                 "--seed", "4", "--out", str(evaluation), "--workers", "1", "--examples", "0"]) == 0
    assert "| blobs |" in capsys.readouterr().out
    assert main(["evaluate", "--task", "wifi-s1", "--checkpoint", str(run / "checkpoint.pt"), "--n", "4",
                 "--seed", "4", "--out", str(evaluation), "--overwrite"]) == 2
    assert "not 'wifi-s1'" in capsys.readouterr().err
    assert main(["train", "--task", "blobs", "--data", str(tmp_path / "nothing"), "--out", str(run)]) == 2
    assert main(["train", "--task", "blobs", "--config", str(config), "--data", str(data),
                 "--out", str(run)]) == 2  # a second run into the first one's folder
    assert "--overwrite" in capsys.readouterr().err
    config.write_text("[task]\nsize_px = 24\n")
    assert main(["train", "--task", "blobs", "--config", str(config), "--data", str(data),
                 "--out", str(run), "--overwrite"]) == 2
    assert "size_px" in capsys.readouterr().err


def _interrupt_on_call(monkeypatch, module, name: str, call: int) -> None:
    """``module.name``'s ``call``-th call raises KeyboardInterrupt, as Ctrl-C landing there."""
    original, calls = getattr(module, name), []

    def wrapped(*args, **kwargs):
        calls.append(None)
        if len(calls) == call:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(module, name, wrapped)


def test_ctrl_c_in_train_and_evaluate_keeps_the_finished_part_and_exits_130(blobs, tmp_path, capsys,
                                                                           monkeypatch):
    import learning.evaluate
    import learning.train

    config = tmp_path / "blobs.toml"
    config.write_text("[task]\nsize_px = 16\n[model]\nwidth = 4\n[train]\nbatch_size = 4\ndevice = 'cpu'\n"
                      "epochs = 4\n")
    data, run, evaluation = tmp_path / "data", tmp_path / "run", tmp_path / "eval"
    assert main(["dataset", "--task", "blobs", "--config", str(config), "--n", "12", "--seed", "4",
                 "--out", str(data), "--workers", "1"]) == 0
    with monkeypatch.context() as patch:  # epoch 1 writes checkpoint.pt (and best.pt); Ctrl-C in epoch 2
        _interrupt_on_call(patch, learning.train, "save_checkpoint", 3)
        assert main(["train", "--task", "blobs", "--config", str(config), "--data", str(data),
                     "--out", str(run)]) == 130
    assert "interrupted (Ctrl-C)" in capsys.readouterr().err
    assert main(["train", "--task", "blobs", "--config", str(config), "--data", str(data), "--out", str(run),
                 "--resume-from", str(run / "checkpoint.pt")]) == 0  # resumed in its own folder: allowed
    # scoring: two calls of score_sample per scene; Ctrl-C in the third scene keeps two
    _interrupt_on_call(monkeypatch, learning.evaluate, "score_sample", 5)
    assert main(["evaluate", "--task", "blobs", "--checkpoint", str(run / "checkpoint.pt"), "--n", "4",
                 "--seed", "4", "--out", str(evaluation), "--workers", "1", "--examples", "0"]) == 130
    summary = json.loads((evaluation / "summary.json").read_text())
    assert summary["interrupted"] == {"scenes_scored": 2, "of": 4}
    assert len(json.loads((evaluation / "results.json").read_text())["samples"]) == 2
    assert "interrupted (Ctrl-C) after 2 of 4 scenes" in capsys.readouterr().err


def test_train_width_and_depth_flags_set_a_new_network_or_grow_the_init_one(blobs, tmp_path, capsys):
    from learning.checkpoint import load_checkpoint

    config = tmp_path / "blobs.toml"
    config.write_text("[task]\nsize_px = 16\n[model]\narch = 'unet'\nwidth = 4\ndepth = 1\n"
                      "[train]\nbatch_size = 4\ndevice = 'cpu'\n")
    data = tmp_path / "data"
    assert main(["dataset", "--task", "blobs", "--config", str(config), "--n", "8", "--seed", "4",
                 "--out", str(data), "--workers", "1"]) == 0
    common = ["train", "--task", "blobs", "--config", str(config), "--data", str(data), "--max-steps", "1"]
    assert main([*common, "--out", str(tmp_path / "a"), "--width", "6"]) == 0
    first = load_checkpoint(tmp_path / "a" / "checkpoint.pt")
    assert (first.model_config.width, first.model_config.depth) == (6, 1)
    assert main([*common, "--out", str(tmp_path / "b"), "--init", str(tmp_path / "a" / "checkpoint.pt"),
                 "--depth", "2", "--schedule", "constant"]) == 0
    grown = load_checkpoint(tmp_path / "b" / "checkpoint.pt")
    assert grown.payload["train_config"]["schedule"] == "constant"
    assert (grown.model_config.width, grown.model_config.depth) == (6, 2)
    assert grown.payload["grown_from"] == {"width": 6, "depth": 1}
    assert main([*common, "--out", str(tmp_path / "c"), "--init", str(tmp_path / "a" / "checkpoint.pt"),
                 "--width", "4"]) == 2
    assert "only grows" in capsys.readouterr().err
