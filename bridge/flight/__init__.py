"""Flight: the fleet of vehicles, their readiness and homes, guided commands, per-autopilot conventions.

:class:`~bridge.flight.fleet.Fleet` reaches the configured vehicles; :mod:`bridge.flight.guided`
launches, repositions and ends a flight by each vehicle's own autopilot convention;
:mod:`bridge.flight.params` reads and sets a vehicle's parameters and :mod:`bridge.flight.preflight`
checks its link-loss failsafe, geofence and return altitude before it is armed.

May import: ``typed_config``, ``bridge``.
"""
