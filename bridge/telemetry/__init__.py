"""Zenoh telemetry: the swarm's publisher and subscriber, key expressions, payload schema and session config.

``SwarmPublisher`` and ``SwarmSubscriber`` are importable from here (``from bridge.telemetry import
SwarmPublisher``), as before the package was divided.

May import: ``typed_config``, ``bridge``.
"""

from bridge.telemetry.pubsub import SwarmPublisher, SwarmSubscriber

__all__ = ["SwarmPublisher", "SwarmSubscriber"]
