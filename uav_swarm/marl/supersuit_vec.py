"""``uav_swarm_v0`` as a SuperSuit vector env: copies of the parallel env, one slot per (copy, agent).

SuperSuit 3.11's wrappers that apply to this env (continuous ``Box`` spaces, every agent present
until all are truncated together) work on the parallel env unchanged, tested in
``tests/marl/test_supersuit.py``: ``clip_actions_v0``, ``normalize_obs_v0``, ``dtype_v0``,
``frame_stack_v1``, ``clip_reward_v0`` and the vector conversions below. Two do not, in SuperSuit 3.11.0:

- ``black_death_v3`` ends an episode only when every agent is terminated *and* truncated
  (``(terminations & truncations).all()``), so over an env that only truncates it steps the
  finished env; it is not needed here anyway, since no UAV leaves before the others.
- ``frame_skip_v0`` draws the number of skipped frames from ``env.unwrapped.np_random``, an
  attribute ``uav_swarm_v0`` does not have (it draws everything from one generator seeded by ``reset``).

Examples:
    >>> from uav_swarm.marl import supersuit_vec_env
    >>> venv = supersuit_vec_env(3, n_uavs=2, max_cycles=50)
    >>> observations, infos = venv.reset(seed=0)
    >>> venv.num_envs, observations.shape
    (6, (6, 260))
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pettingzoo import ParallelEnv

from uav_swarm.env.parallel import parallel_env
from uav_swarm.marl._optional import require

__all__ = ["supersuit_vec_env"]


def supersuit_vec_env(
    num_copies: int,
    *,
    wrap: Callable[[ParallelEnv], ParallelEnv] | None = None,
    num_cpus: int = 0,
    **env_kwargs: Any,
) -> Any:
    """``num_copies`` parallel envs as one gymnasium-style vector env with ``num_copies * n_uavs`` slots.

    ``ss.pettingzoo_env_to_vec_env_v1`` turns each copy's agents into vector slots (agent order),
    then ``ss.concat_vec_envs_v1(..., base_class="gymnasium")`` concatenates the copies. ``reset(seed=s)``
    seeds copy ``i`` with ``s + i``. ``step(actions)`` takes a ``(num_envs, 2)`` array and returns
    observations ``(num_envs, obs_dim)``, rewards (each copy's team reward in each of its slots),
    terminations (never), truncations (at ``max_cycles``) and a list of per-slot info dicts; a
    finished copy resets at once: its slots then return the reset's observations and info dicts, with
    the episode's last observation in ``infos[k]["terminal_observation"]``.

    Args:
        num_copies: Number of independent copies of the env.
        wrap: Applied to each parallel env before it is vectorised, e.g.
            ``lambda env: ss.frame_stack_v1(env, 4)``.
        num_cpus: 0 steps the copies in this process; more runs them in that many worker processes.
        **env_kwargs: Arguments of :func:`~uav_swarm.env.parallel.parallel_env` (``n_uavs``...).

    Raises:
        ImportError: SuperSuit is not installed (``pip install 'uav-swarm[marl]'``).
    """
    ss = require("supersuit")
    env = parallel_env(**env_kwargs)
    if wrap is not None:
        env = wrap(env)
    vec = ss.pettingzoo_env_to_vec_env_v1(env)
    return ss.concat_vec_envs_v1(vec, num_copies, num_cpus=num_cpus, base_class="gymnasium")
