"""One place a run hands its steps and plans to: Zenoh telemetry, the Foxglove recorder, ROS 2.

The loops of ``simulate`` (:mod:`~uav_swarm.runs.simulate`) and ``fly``
(:mod:`~uav_swarm.runs.flight.loop`) build their payloads (:mod:`bridge.telemetry.schema`) once and give
them to :class:`RunOutputs`, which passes each to every sink the run opened:

- ``publisher``: :class:`bridge.telemetry.SwarmPublisher` (Zenoh, stamps in UNIX time);
- ``recorder``: :class:`uav_swarm.runs.outputs.recording.RunRecorder` (MCAP file and/or live Foxglove view,
  at run
  time);
- ``ros``: :class:`uav_swarm.runs.outputs.ros2.node.RunNode` (ROS 2 topics; simulated time for ``simulate``).

A loop whose states arrive one by one (``fly``: as each vehicle's position comes in) hands them to
:meth:`RunOutputs.state` and says so with ``states_on_arrival``: its recorded steps then carry the
states to the recorder only. With no sink, every call returns at once and nothing is built.

Examples:
    >>> outputs = RunOutputs()
    >>> outputs.active
    False
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from bridge.telemetry.schema import Plan, Qos, UavState

if TYPE_CHECKING:
    from bridge.telemetry import SwarmPublisher
    from uav_swarm.runs.outputs.recording import RunRecorder
    from uav_swarm.runs.outputs.ros2.node import RunNode

__all__ = ["RunOutputs"]


class RunOutputs:
    """The sinks of one run (see the module docstring); any may be None.

    Args:
        publisher: The open Zenoh publisher.
        recorder: The Foxglove recorder.
        ros: The open ROS 2 node.
        states_on_arrival: States come through :meth:`state` as they arrive; steps carry them to the
            recorder only.
    """

    def __init__(self, publisher: SwarmPublisher | None = None, recorder: RunRecorder | None = None,
                 ros: RunNode | None = None, *, states_on_arrival: bool = False) -> None:
        self.publisher, self.recorder, self.ros = publisher, recorder, ros
        self.states_on_arrival = states_on_arrival

    @property
    def active(self) -> bool:
        """Whether any sink takes the run's outputs (a loop builds no payload otherwise)."""
        return self.publisher is not None or self.recorder is not None or self.ros is not None

    @property
    def live(self) -> bool:
        """Whether a sink takes states as they arrive (Zenoh or ROS 2)."""
        return self.publisher is not None or self.ros is not None

    def static_scene(self, obstacles_m: np.ndarray, time_s: float = 0.0) -> None:
        """The area and its obstacle segments ``(M, 4)``, kept for the whole run."""
        if self.recorder is not None:
            self.recorder.static_scene(obstacles_m, time_s)
        if self.ros is not None:
            self.ros.static_scene(obstacles_m, time_s)

    def plan(self, time_s: float, plan: Plan) -> None:
        """A new plan, made at run time ``time_s``."""
        if self.publisher is not None:
            self.publisher.publish_plan(plan)
        if self.recorder is not None:
            self.recorder.plan(time_s, plan)
        if self.ros is not None:
            self.ros.plan(time_s, plan)

    def state(self, state: UavState) -> None:
        """One UAV's state as it arrives (``fly``; the UAV's token is the loop's to declare)."""
        if self.publisher is not None:
            self.publisher.publish_state(state, announce=False)
        if self.ros is not None:
            self.ros.state(state)

    def step(self, time_s: float, states: Sequence[UavState], qos: Qos, pedestrians_m: np.ndarray,
             covered: np.ndarray, *, association: np.ndarray | None = None,
             throughput_mbps: np.ndarray | None = None) -> None:
        """One recorded step at run time ``time_s``: the UAVs' states, the QoS, the crowd, who is served.

        ``association`` and ``throughput_mbps`` (each user's UAV and rate) reach ROS 2 summed per UAV; under
        the 802.11 radio the recording draws whom each UAV serves from ``association``.
        """
        if self.publisher is not None:
            if not self.states_on_arrival:
                for state in states:
                    self.publisher.publish_state(state)
            self.publisher.publish_qos(qos)
        if self.recorder is not None:
            self.recorder.step(time_s, states, qos, pedestrians_m, covered, association=association)
        if self.ros is not None:
            self.ros.step(time_s, states, qos, pedestrians_m, covered, with_states=not self.states_on_arrival,
                          association=association, throughput_mbps=throughput_mbps)

    def announce(self, uav_id: int) -> None:
        """UAV ``uav_id`` flies under the planner now (its Zenoh liveliness token)."""
        if self.publisher is not None:
            self.publisher.announce(uav_id)

    def retire(self, uav_id: int) -> None:
        """UAV ``uav_id`` left the swarm (lost or landed)."""
        if self.publisher is not None:
            self.publisher.retire(uav_id)
