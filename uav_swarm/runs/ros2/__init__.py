"""ROS 2 for a run (``--ros2``): a sink of the run's outputs and a source of operator targets.

- :mod:`~uav_swarm.runs.ros2.config`: the ``[ros2]`` table and the process environment ROS 2 needs
  (loopback discovery by default); no ROS import.
- :mod:`~uav_swarm.runs.ros2.messages`: a run's payloads as standard ROS 2 messages (REP 103 / 105).
- :mod:`~uav_swarm.runs.ros2.node`: the node that publishes them and takes operator targets.

Only ``messages`` and ``node`` import ``rclpy`` (the ``ros2`` extra); they are imported when a run asks.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from uav_swarm.runs.ros2.config import Ros2Config, import_rclpy

if TYPE_CHECKING:
    from uav_swarm.runs.ros2.node import RunNode

__all__ = ["Ros2Config", "open_run_node"]


def open_run_node(config: Ros2Config, **kwargs: Any) -> RunNode:
    """The run's ROS 2 node, open (:class:`~uav_swarm.runs.ros2.node.RunNode`'s arguments).

    Raises:
        typed_config.ConfigError: The ``ros2`` extra is not installed (the message names it).
    """
    import_rclpy()
    from uav_swarm.runs.ros2.node import RunNode

    node = RunNode(config, **kwargs)
    node.open()
    return node
