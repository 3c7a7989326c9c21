"""The separation guard (placeholder docstring, replaced below)."""

from uav_swarm.world.guard.fleet import Bounds, Decision, FleetGuard

__all__ = ["Bounds", "Decision", "FleetGuard"]
