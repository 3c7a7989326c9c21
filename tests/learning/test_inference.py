import numpy as np
import pytest
import torch

from learning.inference import SYMMETRIES, apply_symmetry, invert_symmetry, utility_maps
from learning.model import ModelConfig, build_model


def test_the_eight_symmetries_are_distinct_and_invertible():
    x = torch.arange(16.0).reshape(1, 1, 4, 4)
    images = {tuple(apply_symmetry(x, *s).flatten().tolist()) for s in SYMMETRIES}
    assert len(images) == 8
    for s in SYMMETRIES:
        assert torch.equal(invert_symmetry(apply_symmetry(x, *s), *s), x)


@pytest.mark.parametrize("s", SYMMETRIES)
def test_tta_maps_are_equivariant_even_for_a_network_with_coordinates(s):
    torch.manual_seed(0)
    model = build_model(ModelConfig(arch="unet", width=8, depth=2, in_channels=2, coord_channels=True))
    x = np.random.default_rng(1).random((3, 2, 16, 16), dtype=np.float32)
    assert utility_maps(model, x).std() > 1e-3  # a map worth comparing
    moved = apply_symmetry(torch.from_numpy(x), *s).contiguous().numpy()
    expected = apply_symmetry(torch.from_numpy(utility_maps(model, x, tta=True)), *s).numpy()
    np.testing.assert_allclose(utility_maps(model, moved, tta=True), expected, atol=1e-5)
    plain = utility_maps(model, moved)
    assert not np.allclose(plain, expected, atol=1e-5)  # without TTA the network is not equivariant


def test_utility_maps_refuse_wrong_shapes():
    model = build_model(ModelConfig(arch="unet", width=4, depth=2))
    with pytest.raises(ValueError, match="must be"):
        utility_maps(model, np.zeros((2, 3, 8, 8), dtype=np.float32))
    with pytest.raises(ValueError, match="square"):
        utility_maps(model, np.zeros((1, 1, 8, 16), dtype=np.float32), tta=True)
