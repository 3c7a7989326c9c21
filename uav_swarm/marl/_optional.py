"""Lazy imports of the optional multi-agent RL libraries, with an install hint when one is missing."""

from __future__ import annotations

import importlib
from types import ModuleType

INSTALL_HINT = "pip install 'uav-swarm[marl]'"
"""The command that installs TorchRL, TensorDict and SuperSuit beside uav-swarm."""


def require(module: str) -> ModuleType:
    """Import ``module`` or raise an ImportError that names the ``marl`` extra.

    Raises:
        ImportError: The module (or one it needs) is not installed.
    """
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise ImportError(
            f"{module} is needed for this uav_swarm.marl helper but could not be imported ({error}); "
            f"install the multi-agent RL extra: {INSTALL_HINT}") from error
