"""Deprecated: ``uav_swarm.vector_env`` moved to :mod:`uav_swarm.env.vector` (removed in 0.3)."""

import warnings

from uav_swarm.env.vector import UAVSwarmVectorEnv

__all__ = ["UAVSwarmVectorEnv"]

warnings.warn(
    "uav_swarm.vector_env is deprecated; import UAVSwarmVectorEnv from uav_swarm.env.vector",
    DeprecationWarning,
    stacklevel=2,
)
