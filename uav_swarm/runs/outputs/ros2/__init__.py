"""ROS 2 for a run (``--ros2``): a sink of the run's outputs and a source of operator targets.

- :mod:`~uav_swarm.runs.outputs.ros2.config`: the ``[ros2]`` table and the process environment ROS 2 needs
  (loopback discovery by default); no ROS import.
- :mod:`~uav_swarm.runs.outputs.ros2.messages`: a run's payloads as standard ROS 2 messages (REP 103 / 105).
- :mod:`~uav_swarm.runs.outputs.ros2.node`: the node that publishes them and takes operator targets.

Only ``messages`` and ``node`` import ``rclpy`` (the ``ros2`` extra); they are imported when a run asks.

May import: ``typed_config``, ``bridge``, ``uav_swarm.world``, ``uav_swarm.missions``,
``uav_swarm.runs.steering``, ``uav_swarm.runs.outputs.radio_report`` (each UAV's channel, users and colour,
drawn as a recording draws them).
"""

from __future__ import annotations

import logging
from contextlib import ExitStack
from typing import TYPE_CHECKING

from uav_swarm.runs.outputs.ros2.config import Ros2Config, import_rclpy, not_loading
from uav_swarm.runs.steering import OperatorTargets

if TYPE_CHECKING:
    from bridge.geofence import GeofenceConfig
    from uav_swarm.missions.wifi.task import WifiConfig
    from uav_swarm.runs.outputs.ros2.node import RunNode
    from uav_swarm.world.uav import UAVConfig

__all__ = ["Ros2Config", "check_ros2", "open_run_node"]

logger = logging.getLogger(__name__)


def check_ros2() -> None:
    """Whether ROS 2 loads in this process: rclpy and the type support of every message the node uses.

    A run calls it before its heavy work (the planner's network, the engines' timing), so that a missing
    extra or a broken ROS 2 is said at once, in one line.

    Raises:
        typed_config.ConfigError: The ``ros2`` extra is not installed (the message names it), or its
            libraries do not load, e.g. another ROS 2 sourced in the shell takes their place (the message
            names its variables: :func:`uav_swarm.runs.outputs.ros2.config.not_loading`).
    """
    import_rclpy()
    from rosidl_generator_py.import_type_support_impl import UnsupportedTypeSupport

    try:
        from uav_swarm.runs.outputs.ros2.node import load_interfaces

        load_interfaces()
    except (ImportError, UnsupportedTypeSupport) as exc:
        raise not_loading(exc) from exc


def open_run_node(config: Ros2Config, stack: ExitStack, *, swarm: str, n_uavs: int, command: str,
                  sim_time: bool, task: WifiConfig, uav: UAVConfig, geofence: GeofenceConfig
                  ) -> tuple[RunNode, OperatorTargets]:
    """The run's open ROS 2 node (closed with ``stack``) and the operator targets it fills.

    Args:
        config: The ``[ros2]`` table; its ``wait_for_subscriber_s`` is waited here.
        stack: Closes the node when the run ends.
        swarm: The swarm's name (the default namespace).
        n_uavs: UAVs of the run.
        command: ``simulate`` or ``fly`` (the node is ``uav_swarm_<command>``).
        sim_time: Stamps are run times and ``/clock`` is published (``simulate``); else UNIX time.
        task: The area, the coverage radius and the radio association.
        uav: The cruise altitude and the separation minimum.
        geofence: Operator targets must lie inside it.

    Raises:
        typed_config.ConfigError: The ``ros2`` extra is not installed or does not load (:func:`check_ros2`).
    """
    check_ros2()
    from uav_swarm.runs.outputs.ros2.node import RunNode

    area = task.scenario
    steering = OperatorTargets(width_m=area.width_m, height_m=area.height_m, uav=uav, n_uavs=n_uavs,
                               geofence=geofence)
    node = RunNode(config, swarm=swarm, n_uavs=n_uavs, node_name=f"uav_swarm_{command}", sim_time=sim_time,
                   width_m=area.width_m, height_m=area.height_m,
                   coverage_radius_m=task.radio.coverage_radius_m,
                   min_separation_m=uav.min_separation_m, association=task.radio.association_name,
                   steering=steering)
    node.open()
    stack.callback(node.close)
    if config.wait_for_subscriber_s > 0 and not node.wait_for_subscriber(config.wait_for_subscriber_s):
        logger.warning("no ROS 2 subscriber of the poses after %.1f s: flying anyway",
                       config.wait_for_subscriber_s)
    return node, steering
