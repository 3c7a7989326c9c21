"""``uav_swarm_v0`` as a TorchRL environment, through TorchRL's ``PettingZooWrapper`` (parallel API).

Examples:
    >>> from uav_swarm.marl import torchrl_env
    >>> env = torchrl_env(n_uavs=3, max_cycles=50, seed=0)
    >>> env.group_map
    {'agents': ['uav_0', 'uav_1', 'uav_2']}
    >>> rollout = env.rollout(100, break_when_any_done=False)  # resets itself after 50 steps
    >>> rollout["next", "agents", "reward"].shape
    torch.Size([100, 3, 1])
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from uav_swarm.env.parallel import parallel_env
from uav_swarm.marl._optional import require

if TYPE_CHECKING:
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper
    from torchrl.envs.utils import MarlGroupMapType

__all__ = ["torchrl_env"]

_GROUP_MAPS = {"agents": "ALL_IN_ONE_GROUP", "per_agent": "ONE_GROUP_PER_AGENT"}

# TorchRL 0.14 warns for every PettingZoo other than 1.24.3; tests/marl covers PettingZoo 1.27 here.
_VERSION_WARNING = "PettingZoo in TorchRL is tested using version"


def torchrl_env(
    *,
    group_map: str | Mapping[str, Sequence[str]] | MarlGroupMapType = "agents",
    seed: int | None = None,
    return_state: bool = False,
    **env_kwargs: Any,
) -> PettingZooWrapper:
    """The parallel ``uav_swarm_v0`` wrapped in TorchRL's ``PettingZooWrapper``.

    The wrapper's tensordicts hold, for each group ``g``: ``(g, "observation")`` (group size,
    obs_dim) float32, ``(g, "action")`` (group size, 2) bounded by the env's action Box,
    ``(g, "reward")`` (group size, 1) (the team reward, repeated), ``(g, "done" | "terminated" |
    "truncated")`` and ``(g, "info", key)`` for each key of the env's infos; the root
    ``done``/``truncated`` flags are set at ``max_cycles`` (no agent terminates early, so
    ``use_mask`` is not needed) and ``env.rollout(..., break_when_any_done=False)`` resets by
    itself. ``env.reset(seed=s)`` reseeds the env like ``parallel_env().reset(seed=s)``.

    Args:
        group_map: ``"agents"``: one group named ``agents`` holding every UAV (the usual layout for
            MAPPO/IPPO); ``"per_agent"``: one group per UAV (``uav_0``, ...); or any ``group_map``
            that ``PettingZooWrapper`` takes (a ``MarlGroupMapType`` or a dict of group -> agents).
        seed: Seed of the reset that builds the specs (None: unseeded).
        return_state: Add the env's global ``state()`` as the root key ``"state"``.
        **env_kwargs: Arguments of :func:`uav_swarm.env.parallel.parallel_env` (``n_uavs``, ``max_cycles``,
            ``action_mode``, ``scenario={...}``, ``config``, ``scene``, ``render_mode``, ...).

    Raises:
        ImportError: TorchRL is not installed (``pip install 'uav-swarm[marl]'``).
        ValueError: ``group_map`` is an unknown name.
    """
    pettingzoo_lib = require("torchrl.envs.libs.pettingzoo")
    marl_group_map_type = require("torchrl.envs.utils").MarlGroupMapType
    if isinstance(group_map, str):
        if group_map not in _GROUP_MAPS:
            raise ValueError(f"group_map = {group_map!r}: choose one of {sorted(_GROUP_MAPS)} or a dict")
        group_map = marl_group_map_type[_GROUP_MAPS[group_map]]
    elif isinstance(group_map, Mapping):
        group_map = {group: list(agents) for group, agents in group_map.items()}
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_VERSION_WARNING)
        return pettingzoo_lib.PettingZooWrapper(
            env=parallel_env(**env_kwargs), group_map=group_map, seed=seed, return_state=return_state)
