"""Growing a trained U-Net wider or deeper without changing what it computes (Net2Net).

A trained utility network of ``width`` w and ``depth`` d starts a larger one (width W ≥ w, depth
D ≥ d) whose utility map is the same, up to float rounding; training then goes on from there
(``uav-swarm train --init CHECKPOINT --width W --depth D``), so a capacity experiment starts at
the trained network's quality instead of from scratch.

- **Wider** (Chen, Goodfellow and Shlens, *Net2Net*, 2016): each block's new channels copy old
  channels (channel j copies j mod w), and every layer that reads a copied channel splits the old
  weight between the copies by seeded random fractions that sum to 1 (the copies compute the same,
  so the sum is unchanged; unequal fractions let the copies learn apart).
- **Deeper**: a new pooling level at the bottom. Its encoder block starts from the usual random
  initialisation; the new decoder block reads the old bottleneck through identity kernels (its
  ReLU outputs are non-negative, so the ReLUs pass them) and the new level through zero weights,
  which the first gradient step moves.

Only the ``"unet"`` architecture grows; the other fields of the configs must agree.

Example:
    >>> import torch
    >>> from learning.model import ModelConfig, build_model
    >>> small = ModelConfig(arch="unet", width=4, depth=2, coord_channels=True)
    >>> big = small.replace(width=8, depth=3)
    >>> net = build_model(small).eval()
    >>> grown = build_model(big).eval()
    >>> _ = grown.load_state_dict(grow_state_dict(net.state_dict(), small, big, seed=0))
    >>> x = torch.rand(2, 1, 32, 32)
    >>> bool(torch.allclose(net(x), grown(x), atol=1e-5))
    True
"""

from __future__ import annotations

import torch

from learning.model import ModelConfig, build_model

__all__ = ["GrowError", "grow_state_dict"]


class GrowError(ValueError):
    """The networks cannot be grown one into the other."""


def _widths(config: ModelConfig) -> list[int]:
    return [min(config.width * 2**i, config.max_width) for i in range(config.depth + 1)]


class _Space:
    """A channel space of the grown network: old channel of each new channel, and its share."""

    def __init__(self, old: int, new: int, generator: torch.Generator) -> None:
        self.source = torch.arange(new) % old  # (new,)
        raw = 0.5 + torch.rand(new, generator=generator, dtype=torch.float64)  # (new,) in [0.5, 1.5)
        total = torch.zeros(old, dtype=torch.float64).index_add_(0, self.source, raw)  # (old,)
        self.share = (raw / total[self.source]).float()  # (new,), sums to 1 over each old channel's copies

    @staticmethod
    def identity(n: int) -> _Space:
        space = _Space.__new__(_Space)
        space.source, space.share = torch.arange(n), torch.ones(n)
        return space


def _cat(*spaces: _Space) -> _Space:
    """The space of concatenated channels (``torch.cat`` along channels)."""
    space = _Space.__new__(_Space)
    offsets = [0]
    for s in spaces[:-1]:
        offsets.append(offsets[-1] + int(s.source.max()) + 1)
    space.source = torch.cat([s.source + o for s, o in zip(spaces, offsets, strict=True)])
    space.share = torch.cat([s.share for s in spaces])
    return space


def _grow_conv(weight: torch.Tensor, bias: torch.Tensor, inputs: _Space, outputs: _Space
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """A conv's (out, in, k, k) weight and (out,) bias over the grown channel spaces."""
    grown = weight[outputs.source][:, inputs.source] * inputs.share[None, :, None, None]
    return grown.contiguous(), bias[outputs.source].clone()


def _widen(state: dict[str, torch.Tensor], old: ModelConfig, new: ModelConfig, generator: torch.Generator
           ) -> dict[str, torch.Tensor]:
    """``state`` of ``old`` widened to ``new`` (same depth)."""
    old_w, new_w = _widths(old), _widths(new)
    image = _Space.identity(new.in_channels + (2 if new.coord_channels else 0))
    mid = [_Space(o, n, generator) for o, n in zip(old_w, new_w, strict=True)]
    enc = [_Space(o, n, generator) for o, n in zip(old_w, new_w, strict=True)]
    out = dict(state)

    def conv(name: str, inputs: _Space, outputs: _Space) -> None:
        out[f"{name}.weight"], out[f"{name}.bias"] = _grow_conv(
            state[f"{name}.weight"], state[f"{name}.bias"], inputs, outputs)

    inputs = image
    for i in range(old.depth + 1):
        conv(f"encoder.{i}.0", inputs, mid[i])
        conv(f"encoder.{i}.2", mid[i], enc[i])
        inputs = enc[i]
    for k, level in enumerate(reversed(range(old.depth))):
        dec_mid = _Space(old_w[level], new_w[level], generator)
        dec_out = _Space(old_w[level], new_w[level], generator)
        conv(f"decoder.{k}.0", _cat(inputs, enc[level]), dec_mid)
        conv(f"decoder.{k}.2", dec_mid, dec_out)
        inputs = dec_out
    for head in ("head", "peak_head"):
        if f"{head}.weight" in state:
            conv(head, inputs, _Space.identity(1))
    return out


def _deepen(state: dict[str, torch.Tensor], old: ModelConfig, fresh: dict[str, torch.Tensor]
            ) -> dict[str, torch.Tensor]:
    """``state`` of ``old`` with one more pooling level; the new encoder block's weights from ``fresh``."""
    d = old.depth
    bottom = _widths(old)[-1]
    out = {k: v for k, v in state.items() if not k.startswith("decoder.")}
    for key, value in state.items():
        if key.startswith("decoder."):
            _, index, rest = key.split(".", 2)
            out[f"decoder.{int(index) + 1}.{rest}"] = value
    for key in ("0.weight", "0.bias", "2.weight", "2.bias"):
        out[f"encoder.{d + 1}.{key}"] = fresh[f"encoder.{d + 1}.{key}"].clone()
    below = fresh[f"encoder.{d + 1}.2.weight"].shape[0]
    first = torch.zeros(bottom, below + bottom, 3, 3)
    second = torch.zeros(bottom, bottom, 3, 3)
    channels = torch.arange(bottom)
    first[channels, below + channels, 1, 1] = 1.0  # the old bottleneck (the skip) passes; the new level: 0
    second[channels, channels, 1, 1] = 1.0
    out["decoder.0.0.weight"], out["decoder.0.0.bias"] = first, torch.zeros(bottom)
    out["decoder.0.2.weight"], out["decoder.0.2.bias"] = second, torch.zeros(bottom)
    return out


def grow_state_dict(state: dict[str, torch.Tensor], old: ModelConfig, new: ModelConfig, *, seed: int = 0
                    ) -> dict[str, torch.Tensor]:
    """The weights of ``new`` that compute what ``state`` (a network of ``old``) computes.

    Args:
        state: A :class:`learning.model.UtilityNet` state dict of config ``old``.
        old: Its architecture.
        new: The grown architecture: ``width`` and ``depth`` at least ``old``'s, every other field equal.
        seed: Seeds the copies' weight shares and the new level's initialisation.

    Returns:
        A state dict for ``build_model(new)`` (float32 tensors on the CPU).

    Raises:
        GrowError: Not the ``"unet"`` architecture, a smaller width or depth, or other fields differ.
    """
    if old.arch != "unet" or new.arch != "unet":
        raise GrowError(f"only the 'unet' architecture grows (got {old.arch!r} -> {new.arch!r})")
    if new.width < old.width or new.depth < old.depth:
        raise GrowError(f"a network only grows: width {old.width} -> {new.width}, depth {old.depth} -> "
                        f"{new.depth}")
    differ = sorted(k for k, v in old.to_dict().items()
                    if k not in ("width", "depth") and new.to_dict()[k] != v)
    if differ:
        raise GrowError(f"the networks differ in {differ}, not only in width and depth")
    generator = torch.Generator().manual_seed(seed)
    current = {k: v.detach().float().cpu() for k, v in state.items()}
    config = old
    while config.depth < new.depth:
        deeper = config.replace(depth=config.depth + 1)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed + config.depth)
            fresh = build_model(deeper).state_dict()
        current, config = _deepen(current, config, fresh), deeper
    if new.width != config.width:
        current = _widen(current, config, new, generator)
    return current
