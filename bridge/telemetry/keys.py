"""Telemetry key expressions, defined once and validated with :class:`zenoh.KeyExpr`.

``<swarm>`` is one chunk of ``[A-Za-z0-9_-]``; ``<id>`` is a UAV number >= 0.

- ``uav_swarm/<swarm>/uav/<id>/state``: one UAV's state stream.
- ``uav_swarm/<swarm>/plan``: the swarm's placement plan.
- ``uav_swarm/<swarm>/qos``: the swarm's quality of service.
- ``uav_swarm/<swarm>/uav/<id>/alive``: a liveliness token held while the UAV's publisher lives.

Examples:
    >>> state_key("demo", 3)
    'uav_swarm/demo/uav/3/state'
    >>> uav_id_from_key("uav_swarm/demo/uav/3/alive")
    3
"""

from __future__ import annotations

import functools
import re

import zenoh

__all__ = [
    "ROOT",
    "check_swarm_name",
    "swarm_root",
    "state_key",
    "all_states_key",
    "plan_key",
    "qos_key",
    "alive_key",
    "all_alive_key",
    "payload_kind",
    "is_payload_key",
    "uav_id_from_key",
]

ROOT = "uav_swarm"
_SWARM_RE = re.compile(r"[A-Za-z0-9_-]+")
_KEY_RE = re.compile(
    r"uav_swarm/(?P<swarm>[A-Za-z0-9_-]+)/(?:uav/(?P<uav>\d+)/(?P<leaf>state|alive)|(?P<top>plan|qos))")


def check_swarm_name(swarm: str) -> str:
    """Return ``swarm`` if it is one key chunk of ``[A-Za-z0-9_-]``, else raise ValueError."""
    if not isinstance(swarm, str) or not _SWARM_RE.fullmatch(swarm):
        raise ValueError(f"swarm name {swarm!r} is invalid: use one or more of A-Z a-z 0-9 _ -")
    return swarm


def _check_uav_id(uav_id: int) -> int:
    if isinstance(uav_id, bool) or not isinstance(uav_id, int) or uav_id < 0:
        raise ValueError(f"uav_id = {uav_id!r} must be an integer >= 0")
    return uav_id


def _key(text: str) -> str:
    """Validate a key expression with Zenoh and return it in canonical form."""
    return str(zenoh.KeyExpr(text))


def swarm_root(swarm: str) -> str:
    """``uav_swarm/<swarm>/**``: every telemetry key of one swarm (subscriptions and queries)."""
    return _key(f"{ROOT}/{check_swarm_name(swarm)}/**")


def state_key(swarm: str, uav_id: int) -> str:
    """``uav_swarm/<swarm>/uav/<id>/state``: the state stream of one UAV."""
    return _key(f"{ROOT}/{check_swarm_name(swarm)}/uav/{_check_uav_id(uav_id)}/state")


def all_states_key(swarm: str) -> str:
    """``uav_swarm/<swarm>/uav/*/state``: the state streams of every UAV."""
    return _key(f"{ROOT}/{check_swarm_name(swarm)}/uav/*/state")


def plan_key(swarm: str) -> str:
    """``uav_swarm/<swarm>/plan``: the swarm's placement plan."""
    return _key(f"{ROOT}/{check_swarm_name(swarm)}/plan")


def qos_key(swarm: str) -> str:
    """``uav_swarm/<swarm>/qos``: the swarm's quality of service."""
    return _key(f"{ROOT}/{check_swarm_name(swarm)}/qos")


def alive_key(swarm: str, uav_id: int) -> str:
    """``uav_swarm/<swarm>/uav/<id>/alive``: the liveliness token of one UAV."""
    return _key(f"{ROOT}/{check_swarm_name(swarm)}/uav/{_check_uav_id(uav_id)}/alive")


def all_alive_key(swarm: str) -> str:
    """``uav_swarm/<swarm>/uav/*/alive``: the liveliness tokens of every UAV."""
    return _key(f"{ROOT}/{check_swarm_name(swarm)}/uav/*/alive")


@functools.lru_cache(maxsize=4096)
def _key_parts(key: str) -> tuple[str, int | None] | None:
    """(leaf, uav id) of one of our keys (leaf: state, alive, plan or qos), None for any other key."""
    match = _KEY_RE.fullmatch(key)
    if not match:
        return None
    return (match["top"], None) if match["top"] else (match["leaf"], int(match["uav"]))


def payload_kind(key: str) -> str | None:
    """``"state"``, ``"plan"`` or ``"qos"`` for a payload key of some swarm, None for any other key."""
    parts = _key_parts(str(key))
    return None if parts is None or parts[0] == "alive" else parts[0]


def is_payload_key(key: str) -> bool:
    """Whether ``key`` is a state, plan or QoS key of some swarm."""
    return payload_kind(key) is not None


def uav_id_from_key(key: str) -> int | None:
    """The UAV id in a ``.../uav/<id>/state`` or ``.../uav/<id>/alive`` key, None for other keys."""
    parts = _key_parts(str(key))
    return None if parts is None else parts[1]
