"""Deprecated: ``uav_swarm.batched_env`` moved to :mod:`uav_swarm.env.batched` (removed in 0.3)."""

import warnings

from uav_swarm.env.batched import BatchedUAVSwarm

__all__ = ["BatchedUAVSwarm"]

warnings.warn(
    "uav_swarm.batched_env is deprecated; import BatchedUAVSwarm from uav_swarm.env.batched",
    DeprecationWarning,
    stacklevel=2,
)
