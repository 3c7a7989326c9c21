"""The PettingZoo environment and its views for RL libraries.

- :mod:`~uav_swarm.env.parallel`: ``uav_swarm_v0``, the PettingZoo *parallel* environment
  (``parallel_env``, ``raw_env``, the AEC ``env``), re-exported here.
- :mod:`~uav_swarm.env.core`: the batch-first core, B worlds in arrays, under every view.
- :mod:`~uav_swarm.env.observe`: observations, rewards and infos over the batch.
- :mod:`~uav_swarm.env.config`: its configuration (:class:`~uav_swarm.env.config.EnvConfig`).
- :mod:`~uav_swarm.env.actions`: action spaces and the parsing that rejects malformed actions.
- :mod:`~uav_swarm.env.render`: RGB frames and the human viewer.
- :mod:`~uav_swarm.env.batched`: many copies stepped as one batch of arrays.
- :mod:`~uav_swarm.env.vector`: the batch as a ``gymnasium.vector.VectorEnv``.

The environment is imported on first use of one of its names, so that
``uav_swarm.env.config`` can be imported without PettingZoo.

May import: ``typed_config``, ``uav_swarm.world``.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["env", "parallel_env", "raw_env"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        return getattr(importlib.import_module("uav_swarm.env.parallel"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
