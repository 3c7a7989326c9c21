"""What a run fans out to: records, pictures, Foxglove, ROS 2.

Below ``simulate``, ``fly`` and :mod:`uav_swarm.runs.flight` (they import it, never the reverse); may import
``world``, ``planning`` and ``bridge``.

- :mod:`~uav_swarm.runs.outputs.fanout`: the one object both loops hand each step and plan to (Zenoh
  telemetry, the Foxglove recorder, ROS 2).
- :mod:`~uav_swarm.runs.outputs.records`, :mod:`~uav_swarm.runs.outputs.radio_report`: what a run records.
- :mod:`~uav_swarm.runs.outputs.plots`, :mod:`~uav_swarm.runs.outputs.animation`: QoS figures, CSV and the
  scene GIF.
- :mod:`~uav_swarm.runs.outputs.recording`, :mod:`~uav_swarm.runs.outputs.foxglove_scene`,
  :mod:`~uav_swarm.runs.outputs.foxglove_layout`, :mod:`~uav_swarm.runs.outputs.live_view`: ``--record`` and
  ``--live`` through the Foxglove SDK (the only modules that import it).
- :mod:`uav_swarm.runs.outputs.ros2`: ``--ros2``, the run on ROS 2 topics (the only package that imports
  rclpy).

May import: ``typed_config``, ``bridge``, ``uav_swarm.world``, ``uav_swarm.missions``,
``uav_swarm.runs.service``, ``uav_swarm.runs.simulate_config``, ``uav_swarm.runs.steering``.
"""
