"""The radio of ``simulate`` and ``fly``: the 802.11 radio by default, at the UAVs' flight altitude.

A run flies the 802.11 radio (:data:`RUN_PROPAGATION`) unless ``[task.radio] propagation = "paper"`` asks for
the paper's; the learning tasks (``uav-swarm dataset / train / evaluate``) keep the paper's radio unless
their task file says otherwise (:class:`uav_swarm.world.radio_config.RadioConfig`'s own default).

The paper's radio judges horizontal distances: ``task.radio.altitude_m`` must stay 0 (the UAVs fly at
``uav.alt_m`` over a 2-D radio). The 802.11 radio sees each UAV's own altitude (``uav.alt_m`` plus its
layer, :meth:`uav_swarm.world.uav.UAVConfig.altitudes_m`); its experts and channel plans plan at
``task.radio.altitude_m``, which is therefore ``uav.alt_m``: taken from it when not given
(:func:`with_run_radio`, :func:`run_task`), refused when different (:func:`check_radio_altitude`).

Examples:
    >>> data = {"task": {"radio": {"min_user_rate_mbps": 4.0}}, "uav": {"alt_m": 15.0}}
    >>> with_run_radio(data)["task"]["radio"]
    {'min_user_rate_mbps': 4.0, 'propagation': '802.11', 'altitude_m': 15.0}
    >>> with_run_radio({"task": {"radio": {"propagation": "paper"}}})
    {'task': {'radio': {'propagation': 'paper'}}}
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from typed_config import ConfigError
from uav_swarm.missions.wifi.task import WifiConfig
from uav_swarm.world.radio_config import RUN_PROPAGATION, RadioConfig
from uav_swarm.world.uav import UAVConfig

__all__ = ["RUN_PROPAGATION", "with_run_radio", "run_task", "check_radio_altitude", "radio_for_run"]


def with_run_radio(data: Mapping[str, Any]) -> Mapping[str, Any]:
    """``data`` (a run's TOML tables) with the run's radio where ``[task.radio]`` leaves it out.

    ``task.radio.propagation`` not given becomes :data:`RUN_PROPAGATION`; under the 802.11 radio an
    ``altitude_m`` not given (or 0) becomes ``uav.alt_m``. Values given are kept (the configs' own checks
    judge them).
    """
    task = data.get("task", {})
    if not isinstance(task, Mapping):
        return data
    radio = task.get("radio", {})
    if not isinstance(radio, Mapping):
        return data
    if "propagation" not in radio:
        radio = {**radio, "propagation": RUN_PROPAGATION}
    if radio.get("propagation") == "802.11" and not radio.get("altitude_m"):
        uav = data.get("uav")
        alt_m = uav.get("alt_m", UAVConfig.alt_m) if isinstance(uav, Mapping) else UAVConfig.alt_m
        if isinstance(alt_m, (int, float)) and not isinstance(alt_m, bool) and alt_m > 0:
            radio = {**radio, "altitude_m": float(alt_m)}  # else UAVConfig names the wrong value
    return {**data, "task": {**task, "radio": radio}}


def run_task(uav: UAVConfig | None = None) -> WifiConfig:
    """The task of a run given none: strategy 1 on the 802.11 radio at ``uav.alt_m``.

    Examples:
        >>> run_task().radio.association_name
        '802.11 (airtime fairness)'
    """
    alt_m = (uav or UAVConfig()).alt_m
    return WifiConfig(radio=RadioConfig(propagation=RUN_PROPAGATION, altitude_m=alt_m))


def check_radio_altitude(task: WifiConfig, uav: UAVConfig, where: str) -> None:
    """Refuse a radio altitude the run would not fly (module docstring), in one line naming ``where``.

    Raises:
        ConfigError: The paper's radio with ``altitude_m != 0``, or the 802.11 radio with ``altitude_m``
            other than ``uav.alt_m``.
    """
    altitude_m = task.radio.altitude_m
    if task.radio.propagation == "paper":
        if altitude_m != 0.0:
            raise ConfigError(f"{where}.task.radio.altitude_m = {altitude_m}: the paper's radio flies at "
                              "uav.alt_m with 2-D distances; set altitude_m = 0")
    elif altitude_m != uav.alt_m:
        raise ConfigError(f"{where}.task.radio.altitude_m = {altitude_m} differs from uav.alt_m = "
                          f"{uav.alt_m}: the 802.11 radio flies at the UAVs' altitude; leave altitude_m out")


def radio_for_run(task: WifiConfig) -> WifiConfig:
    """The task a run flies: strategy 2 under the paper's radio takes admission control unless told.

    A deployed strategy-2 network limits its stations (docs/simulate.md, admission control); the paper's
    ``station_limit = "off"`` keeps the paper's model. The 802.11 radio's admission on rate is its own.
    """
    if task.strategy == 2 and task.radio.propagation == "paper" and task.radio.station_limit is None:
        return task.replace(radio=task.radio.replace(station_limit="auto"))
    return task
