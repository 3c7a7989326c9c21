from pathlib import Path

import blob_task
import numpy as np
import pytest
from blob_task import BlobTask, make_blob_task

from learning.data import DatasetError, generate_dataset, load_arrays, load_manifest, sample_seed
from learning.executors import ray_session
from learning.loader import ShardDataset
from learning.targets import TargetConfig


def files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """The 20-sample dataset (shards of 6) generated in this process."""
    out = tmp_path_factory.mktemp("reference")
    generate_dataset(make_blob_task, 20, 7, out, shard_size=6, workers=1, progress=False)
    return out


def test_dataset_layout_and_contents(reference):
    manifest, arrays = load_arrays(reference)
    assert manifest["task"] == "blobs" and manifest["n"] == 20 and len(manifest["shards"]) == 4
    assert arrays["inputs"].shape == (20, 1, 32, 32) and arrays["inputs"].dtype == np.float32
    assert arrays["positions"].shape == (20, 10, 2) and arrays["mask"].shape == (20, 10)
    assert arrays["indices"].tolist() == list(range(20))
    task = BlobTask()
    for i in (0, 13):  # a scene regenerated from its stored seed gives the stored sample
        scene = task.sample(np.random.default_rng(int(arrays["seeds"][i])))
        np.testing.assert_array_equal(task.observe(scene), arrays["inputs"][i])
        np.testing.assert_array_equal(task.expert(scene), arrays["positions"][i][arrays["mask"][i]])


def test_same_seed_gives_identical_bytes_with_a_process_pool(reference, tmp_path):
    generate_dataset(make_blob_task, 20, 7, tmp_path, shard_size=6, workers=2, progress=False)
    assert files(tmp_path) == files(reference)


def test_other_seed_or_split_gives_other_scenes(reference, tmp_path):
    generate_dataset(make_blob_task, 20, 7, tmp_path, split="test", shard_size=6, workers=1, progress=False)
    _, a = load_arrays(reference)
    _, b = load_arrays(tmp_path)
    assert not set(a["seeds"].tolist()) & set(b["seeds"].tolist())
    assert sample_seed(7, "train", 3) != sample_seed(8, "train", 3)
    with pytest.raises(ValueError, match="split"):
        sample_seed(7, "nope", 0)


def test_kill_and_resume_loses_nothing(reference, tmp_path):
    class Killed(Exception):
        pass

    written = []

    def kill_after_two(record):
        written.append(record["index"])
        if len(written) == 2:
            raise Killed

    with pytest.raises(Killed):
        generate_dataset(make_blob_task, 20, 7, tmp_path, shard_size=6, workers=1, progress=False,
                         on_shard=kill_after_two)
    assert len(load_manifest(tmp_path)["shards"]) == 2
    with pytest.raises(DatasetError, match="incomplete"):
        load_arrays(tmp_path)
    resumed = []
    generate_dataset(make_blob_task, 20, 7, tmp_path, shard_size=6, workers=1, progress=False,
                     on_shard=lambda r: resumed.append(r["index"]))
    assert sorted(resumed) == sorted({0, 1, 2, 3} - set(written))  # finished shards are not redone
    assert files(tmp_path) == files(reference)


def test_corrupt_shard_is_detected_and_regenerated(reference, tmp_path):
    generate_dataset(make_blob_task, 20, 7, tmp_path, shard_size=6, workers=1, progress=False)
    shard = tmp_path / "shard-00001.npz"
    shard.write_bytes(shard.read_bytes()[:-10] + b"0123456789")
    with pytest.raises(DatasetError, match="SHA-256"):
        load_arrays(tmp_path)
    redone = []
    generate_dataset(make_blob_task, 20, 7, tmp_path, shard_size=6, workers=1, progress=False,
                     on_shard=lambda r: redone.append(r["index"]))
    assert redone == [1] and files(tmp_path) == files(reference)


def test_folder_of_another_dataset_is_refused(reference):
    with pytest.raises(DatasetError, match="seed"):
        generate_dataset(make_blob_task, 20, 8, reference, shard_size=6, workers=1, progress=False)


def test_local_and_ray_shards_are_byte_identical(reference, tmp_path):
    import ray

    ray.cloudpickle.register_pickle_by_value(blob_task)  # the test task is not an installed module
    with ray_session(num_cpus=2, log_to_driver=False):  # local, loopback only
        generate_dataset(make_blob_task, 20, 7, tmp_path, shard_size=6, executor="ray", progress=False)
    assert files(tmp_path) == files(reference)


def test_loader_renders_normalised_targets_and_augments_consistently(reference):
    _, arrays = load_arrays(reference)
    cfg = TargetConfig(alpha2=25.5, sigma2=4.0)
    row = next(i for i in range(20) if arrays["mask"][i].sum() == 1)  # a scene with one blob
    plain = ShardDataset(arrays, cfg, indices=[row])
    x, y = plain[0]
    assert x.shape == (1, 32, 32) and y.shape == (1, 32, 32)
    cx, cy = arrays["positions"][row, 0].astype(int)
    assert float(y[0, cy, cx]) == pytest.approx(1.1)  # (alpha1 + alpha2) / alpha1
    augmented = ShardDataset(arrays, cfg, indices=[row], augment=True, augment_seed=3)
    seen = set()
    for epoch in range(16):
        augmented.set_epoch(epoch)
        xa, ya = augmented[0]
        peak = np.unravel_index(int(ya[0].argmax()), (32, 32))
        assert np.unravel_index(int(xa[0].argmax()), (32, 32)) == peak
        seen.add(peak)
    assert len(seen) > 1  # the symmetries did move the blob
