import functools

import pytest
import torch
from blob_task import BlobConfig, BlobTask

from learning.checkpoint import load_checkpoint
from learning.data import generate_dataset
from learning.grow import GrowError, grow_state_dict
from learning.model import ModelConfig, build_model
from learning.train import TrainConfig, train

SMALL_UNET = ModelConfig(arch="unet", in_channels=2, width=4, depth=2, max_width=16, coord_channels=True)


def trained_like(config, seed=0):
    """A network with weights away from the initialisation (biases too), as training leaves them."""
    torch.manual_seed(seed)
    net = build_model(config)
    with torch.no_grad():
        for p in net.parameters():
            p.add_(0.05 * torch.randn_like(p))
    return net.eval()


@pytest.mark.parametrize(("width", "depth"), [(8, 2), (4, 3), (8, 3), (12, 4), (4, 2)])
def test_a_grown_network_computes_the_same_map(width, depth):
    net = trained_like(SMALL_UNET)
    big = SMALL_UNET.replace(width=width, depth=depth)
    grown = build_model(big).eval()
    grown.load_state_dict(grow_state_dict(net.state_dict(), SMALL_UNET, big, seed=3))  # strict: all keys fit
    x = torch.rand(3, 2, 32, 32)
    with torch.no_grad():
        before, after = net(x), grown(x)
    assert before.abs().max() > 0.01  # a map that is not flat, so the comparison means something
    torch.testing.assert_close(after, before, atol=1e-5, rtol=1e-4)
    if width > SMALL_UNET.width:
        w = grown.state_dict()["encoder.1.0.weight"]  # reads the copied channels of block 0
        assert not torch.allclose(w[:, 0], w[:, SMALL_UNET.width])


def test_a_peak_head_and_the_cap_on_widths_grow_too():
    small = SMALL_UNET.replace(peak_head=True, max_width=8)
    net = trained_like(small)
    big = small.replace(width=8, depth=3)  # widths 4/8/8 -> 8/8/8/8: the capped levels are kept
    grown = build_model(big).eval()
    grown.load_state_dict(grow_state_dict(net.state_dict(), small, big))
    x = torch.rand(2, 2, 16, 16)
    with torch.no_grad():
        for a, b in zip(net.forward_with_peaks(x), grown.forward_with_peaks(x), strict=True):
            torch.testing.assert_close(b, a, atol=1e-5, rtol=1e-4)


def test_growing_is_seeded():
    state = trained_like(SMALL_UNET).state_dict()
    big = SMALL_UNET.replace(width=8, depth=3)
    one, two, other = (grow_state_dict(state, SMALL_UNET, big, seed=s) for s in (1, 1, 2))
    assert all(torch.equal(one[k], two[k]) for k in one)
    assert not all(torch.equal(one[k], other[k]) for k in one)


@pytest.mark.parametrize(("old", "new", "match"), [
    (SMALL_UNET, SMALL_UNET.replace(width=2), "only grows"),
    (SMALL_UNET, SMALL_UNET.replace(depth=1), "only grows"),
    (SMALL_UNET, SMALL_UNET.replace(coord_channels=False), "coord_channels"),
    (ModelConfig(arch="paper", width=4), ModelConfig(arch="paper", width=8), "unet"),
])
def test_what_cannot_grow_says_why(old, new, match):
    with pytest.raises(GrowError, match=match):
        grow_state_dict(build_model(old).state_dict(), old, new)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("data")
    generate_dataset(functools.partial(BlobTask, BlobConfig(size_px=16, max_blobs=2)), 20, 3, out,
                     shard_size=10, workers=1, progress=False)
    return out


def test_training_grows_its_init_network_and_records_it(data, tmp_path):
    cfg = TrainConfig(epochs=1, batch_size=8, val_fraction=0.2, device="cpu")
    first = train(data, tmp_path / "first", model_config=SMALL_UNET.replace(in_channels=1), train_config=cfg,
                  progress=False)
    frozen = cfg.replace(lr=1e-12, schedule="constant")
    grown = train(data, tmp_path / "grown", train_config=frozen, init=first.best_checkpoint, grow=(8, 3),
                  progress=False)
    start, after = load_checkpoint(first.best_checkpoint), load_checkpoint(grown.checkpoint)
    assert (after.model_config.width, after.model_config.depth) == (8, 3)
    assert after.payload["grown_from"] == {"width": 4, "depth": 2}
    x = torch.rand(2, 1, 16, 16)
    with torch.no_grad():
        torch.testing.assert_close(after.model.eval()(x), start.model.eval()(x), atol=1e-4, rtol=1e-3)
    with pytest.raises(ValueError, match="grow needs init"):
        train(data, tmp_path / "none", train_config=cfg, grow=(8, 3), progress=False)
