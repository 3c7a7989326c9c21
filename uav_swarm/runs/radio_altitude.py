"""The radio's height in ``simulate`` and ``fly``: the paper's radio is 2-D, the 802.11 radio flies.

The paper's radio judges horizontal distances: ``task.radio.altitude_m`` must stay 0 (the UAVs fly at
``uav.alt_m`` over a 2-D radio). The 802.11 radio sees each UAV's own altitude (``uav.alt_m`` plus its
layer, :meth:`uav_swarm.world.uav.UAVConfig.altitudes_m`); its experts and channel plans plan at
``task.radio.altitude_m``, which is therefore ``uav.alt_m``: taken from it when not given
(:func:`with_flight_altitude`), refused when different (:func:`check_radio_altitude`).

Examples:
    >>> data = {"task": {"radio": {"propagation": "802.11"}}, "uav": {"alt_m": 15.0}}
    >>> with_flight_altitude(data)["task"]["radio"]["altitude_m"]
    15.0
    >>> with_flight_altitude({"task": {"strategy": 2}})
    {'task': {'strategy': 2}}
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from typed_config import ConfigError
from uav_swarm.missions.wifi.task import WifiConfig
from uav_swarm.world.uav import UAVConfig

__all__ = ["with_flight_altitude", "check_radio_altitude", "radio_for_run"]


def with_flight_altitude(data: Mapping[str, Any]) -> Mapping[str, Any]:
    """``data`` (a run's TOML tables) with ``task.radio.altitude_m = uav.alt_m`` under the 802.11 radio.

    Only where ``[task.radio]`` sets ``propagation = "802.11"`` and gives no ``altitude_m`` (or 0); anything
    else is returned as it is (the configs' own checks judge it).
    """
    task = data.get("task")
    if not isinstance(task, Mapping):
        return data
    radio = task.get("radio")
    if not isinstance(radio, Mapping) or radio.get("propagation") != "802.11" or radio.get("altitude_m"):
        return data
    uav = data.get("uav")
    alt_m = uav.get("alt_m", UAVConfig.alt_m) if isinstance(uav, Mapping) else UAVConfig.alt_m
    if not isinstance(alt_m, (int, float)) or isinstance(alt_m, bool) or not alt_m > 0:
        return data  # UAVConfig names a wrong value; check_radio_altitude refuses a zero
    return {**data, "task": {**task, "radio": {**radio, "altitude_m": float(alt_m)}}}


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
