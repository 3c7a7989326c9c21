"""The utility network: a raster in, a utility map of the same size out.

Two architectures, chosen by :class:`ModelConfig.arch`:

- ``"paper"``: the paper's network, the baseline. Encoder 2×conv-w, maxpool,
  2×conv-2w, maxpool, 2×conv-4w (3×3 kernels, ReLU; w = 32 gives 32/64/128);
  light decoder conv-4wᵀ, ×2 upsampling, conv-2wᵀ, ×2 upsampling, conv-wᵀ, and a
  1×1 convolution to one channel.
- ``"unet"``: our improvement. The same blocks with ``depth`` poolings and skip
  connections (U-Net), so the decoder sees both the fine detail and the wide
  receptive field of the bottleneck.

Either may add CoordConv channels (the pixel's normalised x and y in [-1, 1])
to the input, which lets the network learn position-dependent rules such as
staying away from the border.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import torch
import torch.nn.functional as F
from torch import nn

from typed_config import Config, ConfigError, param

__all__ = ["ModelConfig", "UtilityNet", "build_model", "with_memory_format"]


@dataclass(frozen=True)
class ModelConfig(Config):
    """Architecture of the utility network."""

    arch: Literal["paper", "unet"] = param("paper", doc="'paper' (baseline) or 'unet' (skip connections)")
    in_channels: int = param(1, ge=1, le=64, doc="input raster channels C (the task's channels)")
    width: int = param(32, ge=1, le=256, doc="channels of the first block; doubled after each pooling")
    depth: int = param(2, ge=1, le=5, doc="number of 2× poolings (the paper's network has 2)")
    max_width: int = param(128, ge=1, le=1024, doc="cap on the channels of any block")
    coord_channels: bool = param(False, doc="append normalised x, y coordinate channels to the input")
    vector_channels: tuple[int, ...] = param(
        (), doc="input channels holding vector components, as (x, y) index pairs flattened (the task's); "
        "test-time augmentation turns them with the raster")
    peak_head: bool = param(
        False, doc="a second 1x1 head predicting the expert positions as a sharp heatmap, trained with a "
        "focal loss beside the utility's MSE (learning.losses); inference reads the utility map only")

    def check(self) -> None:
        """The paper's network has exactly two poolings."""
        if self.arch == "paper" and self.depth != 2:
            raise ConfigError(f"ModelConfig.depth = {self.depth}: the 'paper' arch needs depth = 2")


def _double_conv(c_in: int, c_out: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, padding=1), nn.ReLU(inplace=True),
        nn.Conv2d(c_out, c_out, 3, padding=1), nn.ReLU(inplace=True),
    )


def _transpose_conv(c_in: int, c_out: int) -> nn.Sequential:
    return nn.Sequential(nn.ConvTranspose2d(c_in, c_out, 3, padding=1), nn.ReLU(inplace=True))


class _CoordChannels(nn.Module):
    """Appends x and y in [-1, 1] as two channels; the grid is built once per shape and device."""

    def __init__(self) -> None:
        super().__init__()
        self._grid: torch.Tensor | None = None

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, _, h, w = x.shape
        grid = self._grid
        if grid is None or grid.shape[-2:] != (h, w) or grid.device != x.device or grid.dtype != x.dtype:
            ys = torch.linspace(-1.0, 1.0, h, device=x.device, dtype=x.dtype)
            xs = torch.linspace(-1.0, 1.0, w, device=x.device, dtype=x.dtype)
            gy, gx = torch.meshgrid(ys, xs, indexing="ij")
            grid = self._grid = torch.stack([gx, gy])[None]  # (1, 2, h, w)
        return torch.cat([x, grid.expand(b, -1, -1, -1)], dim=1)  # (b, C+2, h, w)


class UtilityNet(nn.Module):
    """Maps a ``(B, C, h, w)`` raster to a ``(B, 1, h, w)`` utility map (any h, w)."""

    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        self.config = config
        self.coords = _CoordChannels() if config.coord_channels else None
        c_in = config.in_channels + (2 if config.coord_channels else 0)
        widths = [min(config.width * 2**i, config.max_width) for i in range(config.depth + 1)]
        self.encoder = nn.ModuleList()
        for w in widths:
            self.encoder.append(_double_conv(c_in, w))
            c_in = w
        self.decoder = nn.ModuleList()
        if config.arch == "paper":
            # conv-4wᵀ at the bottom, then (upsample, conv-ᵀ) per pooling back to width w.
            self.decoder.append(_transpose_conv(c_in, c_in))
            for w in reversed(widths[:-1]):
                self.decoder.append(_transpose_conv(c_in, w))
                c_in = w
        else:
            for w in reversed(widths[:-1]):
                self.decoder.append(_double_conv(c_in + w, w))
                c_in = w
        self.head = nn.Conv2d(c_in, 1, 1)
        self.peak_head = nn.Conv2d(c_in, 1, 1) if config.peak_head else None
        if self.peak_head is not None and self.peak_head.bias is not None:
            # CenterNet's prior: every pixel starts at p = sigmoid(-2.19) = 0.1
            nn.init.constant_(self.peak_head.bias, -2.19)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Utility map of a batch of rasters.

        Args:
            x: ``(B, C, h, w)`` float rasters.

        Returns:
            ``(B, 1, h, w)`` utility maps (in units of ``R / α1``, see :mod:`learning.targets`).
        """
        return self.head(self._features(x))  # (B, 1, h, w)

    def forward_with_peaks(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The utility maps and the peak head's logits, both ``(B, 1, h, w)`` (needs ``peak_head``)."""
        if self.peak_head is None:
            raise ValueError("this network has no peak head (ModelConfig.peak_head = false)")
        features = self._features(x)
        return self.head(features), self.peak_head(features)

    def _features(self, x: torch.Tensor) -> torch.Tensor:
        """The last decoder block's ``(B, w, h, w)`` features."""
        if self.coords is not None:
            x = self.coords(x)  # (B, C+2, h, w)
        skips = []
        for i, block in enumerate(self.encoder):
            if i > 0:
                x = F.max_pool2d(x, 2)  # (B, c, h/2^i, w/2^i)
            x = block(x)
            skips.append(x)
        skips.pop()  # the bottleneck is x itself
        if self.config.arch == "paper":
            x = self.decoder[0](x)  # (B, 4w, h/4, w/4)
            for layer, skip in zip(self.decoder[1:], reversed(skips), strict=True):
                x = layer(F.interpolate(x, size=skip.shape[-2:], mode="nearest"))  # (B, c, 2×)
        else:
            for layer, skip in zip(self.decoder, reversed(skips), strict=True):
                x = F.interpolate(x, size=skip.shape[-2:], mode="bilinear", align_corners=False)
                x = layer(torch.cat([x, skip], dim=1))  # (B, c, 2×)
        return x


def build_model(config: ModelConfig) -> UtilityNet:
    """A freshly initialised :class:`UtilityNet` for ``config``."""
    return UtilityNet(config)


def with_memory_format(model: UtilityNet, memory_format: torch.memory_format,
                       device: torch.device | str | None = None) -> UtilityNet:
    """``model`` moved to ``device`` (when given) with its 4-D weights in ``memory_format``, in place.

    Examples:
        >>> net = with_memory_format(build_model(ModelConfig(in_channels=1)), torch.channels_last)
        >>> net.head.weight.is_contiguous(memory_format=torch.channels_last)
        True
    """
    moved = model.to(device) if device is not None else model
    return moved.to(memory_format=memory_format)  # type: ignore[call-overload]  # torch's stubs omit it
