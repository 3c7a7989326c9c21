"""The grid of an (α2, σ2) search: inclusive ranges parsed from ``"start:stop:step"`` text."""

from __future__ import annotations

import math
from dataclasses import dataclass

from typed_config import Config, ConfigError, param

__all__ = ["Point", "parse_grid", "SearchConfig"]

Point = tuple[float, float]
"""A grid point ``(alpha2, sigma2)``."""


def parse_grid(text: str, name: str, *, positive: bool = False) -> tuple[float, ...]:
    """Values of an inclusive range ``"start:stop:step"`` (or a single value ``"x"``).

    Args:
        text: E.g. ``"20:60:10"`` -> ``(20.0, 30.0, 40.0, 50.0, 60.0)``.
        name: The field's name, for error messages.
        positive: Values must be > 0 (otherwise >= 0).

    Raises:
        ConfigError: Malformed text, ``step <= 0``, ``stop < start`` (empty range),
            a value out of range, or more than 1,000 values.

    Examples:
        >>> parse_grid("20:60:10", "alpha2")
        (20.0, 30.0, 40.0, 50.0, 60.0)
        >>> parse_grid("0.5:1.5:0.5", "sigma2", positive=True)
        (0.5, 1.0, 1.5)
    """
    parts = text.split(":")
    try:
        numbers = [float(p) for p in parts]
    except ValueError:
        numbers = []
    if len(numbers) not in (1, 3) or not all(math.isfinite(v) for v in numbers):
        raise ConfigError(f"{name} = {text!r} must be 'start:stop:step' (inclusive) or one number")
    start, stop, step = (numbers[0], numbers[0], 1.0) if len(numbers) == 1 else numbers
    if step <= 0:
        raise ConfigError(f"{name} = {text!r}: step = {step:g} must be > 0")
    if stop < start:
        raise ConfigError(f"{name} = {text!r} is an empty range: stop = {stop:g} < start = {start:g}")
    count = math.floor((stop - start) / step + 1e-9) + 1
    if count > 1000:
        raise ConfigError(f"{name} = {text!r} has {count} values: allowed at most 1000")
    values = tuple(round(start + i * step, 9) for i in range(count))
    if positive and values[0] <= 0:
        raise ConfigError(f"{name} = {text!r}: values must be > 0 (got {values[0]:g})")
    if values[0] < 0:
        raise ConfigError(f"{name} = {text!r}: values must be >= 0 (got {values[0]:g})")
    return values


@dataclass(frozen=True)
class SearchConfig(Config):
    """The grid and the per-trial threads of a search.

    The default grid is the one of the README's Wi-Fi searches: α2 20-60 and σ2 5-45 px, step 10
    (the paper's 5x5 shape; σ2 scaled to our 64 px rasters).
    """

    alpha2: str = param("20:60:10", doc="α2 grid, inclusive 'start:stop:step' (>= 0), target units")
    sigma2: str = param("5:45:10", doc="σ2 grid, inclusive 'start:stop:step' (> 0), pixels")
    threads: int = param(1, ge=1, le=256, doc="torch threads per trial (part of the results' identity)")

    def check(self) -> None:
        """Both grids parse into non-empty ranges of allowed values."""
        parse_grid(self.alpha2, "SearchConfig.alpha2")
        parse_grid(self.sigma2, "SearchConfig.sigma2", positive=True)

    @property
    def alpha2_values(self) -> tuple[float, ...]:
        """The α2 values, increasing."""
        return parse_grid(self.alpha2, "SearchConfig.alpha2")

    @property
    def sigma2_values(self) -> tuple[float, ...]:
        """The σ2 values, increasing."""
        return parse_grid(self.sigma2, "SearchConfig.sigma2", positive=True)

    @property
    def points(self) -> list[Point]:
        """Every ``(alpha2, sigma2)`` of the grid, α2-major."""
        return [(a, s) for a in self.alpha2_values for s in self.sigma2_values]
