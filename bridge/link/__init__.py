"""MAVLink links: connections and their reader, frames on the wire, signing, and the vehicle state they feed.

Nothing here knows about missions or flying: it moves messages to and from vehicles and folds
what they say into :class:`~bridge.link.vehicle_state.VehicleState` snapshots.

May import: ``typed_config``, ``bridge``.
"""
