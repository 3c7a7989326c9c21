"""Validating the actions handed to :class:`~uav_swarm.env.parallel.raw_env`: agents, shapes, dtypes, values.

Examples:
    >>> agents, values = parse_actions({"uav_1": [0.5, -1.0]}, {"uav_0": 0, "uav_1": 1})
    >>> agents, values.tolist()
    ([1], [[0.5, -1.0]])
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NoReturn

import numpy as np

__all__ = ["parse_actions"]


def parse_actions(actions: Mapping[str, Any], agent_index: Mapping[str, int]) -> tuple[list[int], np.ndarray]:
    """The acting agents' indices and their actions as a ``(k, 2)`` float64 array (not yet clipped).

    Args:
        actions: Agent name to a length-2 action.
        agent_index: Every possible agent's name to its index.

    Raises:
        ValueError: An unknown agent, an action of another shape or a non-numeric dtype, or NaN / inf;
            the message names the first offending agent.
    """
    given = [agent_index.get(agent, -1) for agent in actions]
    if -1 in given:
        unknown = next(agent for agent in actions if agent not in agent_index)
        raise ValueError(f"unknown agent {unknown!r}: the agents are {list(agent_index)}")
    try:
        values = np.array(list(actions.values())) if given else np.zeros((0, 2))
    except ValueError:  # ragged shapes
        values = None
    if values is None or values.dtype.kind not in "fiu" or values.shape != (len(given), 2):
        _raise_bad_action(actions)
    values = values.astype(np.float64, copy=False)
    finite = np.isfinite(values).all(axis=1)
    if not finite.all():
        bad = int(np.argmin(finite))
        raise ValueError(f"action of {list(actions)[bad]!r} contains NaN or inf: {values[bad].tolist()}")
    return given, values


def _raise_bad_action(actions: Mapping[str, Any]) -> NoReturn:
    """Raise a ValueError naming the first agent whose action has a bad shape or dtype."""
    for agent, action in actions.items():
        value = np.asarray(action)
        if value.shape != (2,):
            raise ValueError(f"action of {agent!r} must have shape (2,), got {value.shape}")
        if value.dtype.kind not in "fiu":
            raise ValueError(f"action of {agent!r} must be a float or int array, got dtype {value.dtype}")
    raise ValueError(f"actions must be arrays of shape (2,) of floats or ints, got {actions!r}")
