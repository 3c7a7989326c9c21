"""Adapters from ``uav_swarm_v0`` to the multi-agent RL libraries people use (``uav-swarm[marl]``).

- :func:`torchrl_env`: TorchRL's ``PettingZooWrapper`` around the parallel env (grouped agents).
- :func:`supersuit_vec_env`: SuperSuit's vector env, copies of the parallel env with one slot per agent.

Both import their library only when called; a missing library raises an ImportError that says
``pip install 'uav-swarm[marl]'``.

May import: ``typed_config``, ``uav_swarm.world``, ``uav_swarm.missions``, ``uav_swarm.env``,
``uav_swarm.planning``, ``uav_swarm.runs``.
"""

from uav_swarm.marl.supersuit_vec import supersuit_vec_env
from uav_swarm.marl.torchrl_pettingzoo import torchrl_env

__all__ = ["supersuit_vec_env", "torchrl_env"]
