"""MAPPO (TorchRL) on the batched environment: outputs, reproducibility, resume, the trained policy."""

import csv
import json

import numpy as np
import pytest
import torch

from uav_swarm.marl.mappo import MappoConfig, load_policy, train_mappo  # noqa: E402

SMALL = MappoConfig(n_uavs=2, num_envs=4, max_cycles=10, frames_per_batch=40, total_frames=120,
                    minibatch_size=20, epochs=2, hidden=16, torch_threads=1, seed=4)


@pytest.fixture(autouse=True)
def _small_world(monkeypatch: pytest.MonkeyPatch) -> None:
    """The tiny world of the wrapper tests instead of the 200 m Wi-Fi world."""
    from marl_world import SMALL_WORLD

    original = MappoConfig.env_config
    monkeypatch.setattr(MappoConfig, "env_config", lambda self: original(self).replace(**{
        "density_shape": SMALL_WORLD["density_shape"], "patch_px": SMALL_WORLD["patch_px"],
        "scenario": original(self).scenario.replace(**SMALL_WORLD["scenario"])}))


def test_training_writes_curve_policy_and_summary(tmp_path) -> None:
    summary = train_mappo(SMALL, tmp_path, progress=False)
    rows = list(csv.DictReader((tmp_path / "curve.csv").open()))
    assert [int(r["frames"]) for r in rows] == [40, 80, 120]
    assert summary["frames"] == 120 and summary["iterations"] == 3
    assert json.loads((tmp_path / "summary.json").read_text())["frames"] == 120
    assert (tmp_path / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    policy = load_policy(tmp_path / "policy.pt")
    obs = np.random.default_rng(0).uniform(0, 1, size=(2, policy.actor[0].mean.numel())).astype(np.float32)
    action = policy.act(obs)
    assert action.shape == (2, 2) and np.all(np.abs(action) <= 1.0)


def test_same_seed_same_policy(tmp_path) -> None:
    train_mappo(SMALL, tmp_path / "a", progress=False)
    train_mappo(SMALL, tmp_path / "b", progress=False)
    a = torch.load(tmp_path / "a" / "policy.pt", weights_only=False)["actor"]
    b = torch.load(tmp_path / "b" / "policy.pt", weights_only=False)["actor"]
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    c = torch.load(tmp_path / "a" / "checkpoint.pt", weights_only=False)
    assert c["frames"] == 120 and len(c["history"]) == 3


def test_resume_continues_and_refuses_other_networks(tmp_path) -> None:
    train_mappo(SMALL, tmp_path, progress=False)
    summary = train_mappo(SMALL.replace(total_frames=200), tmp_path, resume=True, progress=False)
    assert summary["frames"] == 200 and summary["iterations"] == 5
    with pytest.raises(ValueError, match="hidden"):
        train_mappo(SMALL.replace(hidden=32), tmp_path, resume=True, progress=False)


def test_load_policy_rejects_other_files(tmp_path) -> None:
    torch.save({"format": "something else"}, tmp_path / "x.pt")
    with pytest.raises(ValueError, match="not a MAPPO policy"):
        load_policy(tmp_path / "x.pt")
