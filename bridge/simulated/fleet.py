"""A fleet of simulated autopilots on 127.0.0.1, each on its own home along a launch line.

:class:`SimulatedFleet` starts one :class:`~bridge.simulated.ardupilot.ArduCopter` or
:class:`~bridge.simulated.px4.Px4Copter` per endpoint of a bridge config, so that ``uav-swarm fly`` (or
any ground station) flies them exactly as it flies real SITL or hardware over that config: vehicle
``i`` (in the config's order) stands ``i * spacing_m`` East of the config's ``[home]``, answers with the
config's system id, and takes the fleet's :class:`~bridge.simulated.dynamics.Realism` (each vehicle its
own random stream from ``seed``) and parameter values. Only loopback endpoints are served.

:func:`fleet_bridge_config` writes the bridge config of a new fleet: ``n`` vehicles on free UDP ports of
127.0.0.1 around the default home, with a roomy geofence.

Examples:
    >>> from bridge.config import BridgeConfig
    >>> config = BridgeConfig.from_dict({"vehicles": [{"system_id": 1, "url": "udpin:127.0.0.1:14590"}]})
    >>> with SimulatedFleet("px4", config) as fleet:
    ...     [(v.system_id, type(v).__name__, v.url) for v in fleet.vehicles]
    [(1, 'Px4Copter', 'udpout:127.0.0.1:14590')]
"""

from __future__ import annotations

import socket
from collections.abc import Mapping
from types import TracebackType

import numpy as np

from bridge.config import BridgeConfig
from bridge.geo import Home, enu_to_geodetic
from bridge.simulated.ardupilot import FAILSAFE_ON as ARDUPILOT_FAILSAFE
from bridge.simulated.ardupilot import ArduCopter
from bridge.simulated.dynamics import Realism
from bridge.simulated.px4 import FAILSAFE_ON as PX4_FAILSAFE
from bridge.simulated.px4 import Px4Copter

__all__ = ["AUTOPILOTS", "SimulatedFleet", "launch_home", "vehicle_url", "fleet_bridge_config",
           "free_udp_port"]

AUTOPILOTS = {"ardupilot": ArduCopter, "px4": Px4Copter}
"""The autopilots a fleet can be made of."""
_FAILSAFE = {"ardupilot": ARDUPILOT_FAILSAFE, "px4": PX4_FAILSAFE}
_LOOPBACK = ("127.0.0.1", "localhost")
_OPPOSITE = {"udpin": "udpout", "udpout": "udpin", "tcp": "tcpin"}


def launch_home(index: int, spacing_m: float = 10.0, origin: Home | None = None) -> Home:
    """Where vehicle ``index`` of a fleet stands: ``spacing_m`` apart going East from ``origin``."""
    origin = origin or Home()
    lat_deg, lon_deg, _ = enu_to_geodetic(origin, index * spacing_m, 0.0, 0.0)
    return Home(lat_deg=lat_deg, lon_deg=lon_deg, alt_m=origin.alt_m)


def vehicle_url(ground_station_url: str) -> str:
    """The vehicle's end of a ground station's loopback endpoint (``udpin:`` -> ``udpout:``, ...).

    >>> vehicle_url("udpin:127.0.0.1:14540"), vehicle_url("tcp:127.0.0.1:5760")
    ('udpout:127.0.0.1:14540', 'tcpin:127.0.0.1:5760')
    """
    kind, _, address = ground_station_url.partition(":")
    host = address.rpartition(":")[0]
    if kind not in _OPPOSITE or host not in _LOOPBACK:
        raise ValueError(f"vehicle url {ground_station_url!r}: a simulated vehicle serves only udpin:, "
                         f"udpout: or tcp: endpoints on 127.0.0.1")
    return f"{_OPPOSITE[kind]}:{address}"


def free_udp_port() -> int:
    """A UDP port of 127.0.0.1 that nothing listens on now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def fleet_bridge_config(n: int, *, home: Home | None = None, half_width_m: float = 500.0) -> str:
    """The bridge config (TOML) of a new fleet of ``n`` vehicles on free UDP ports of 127.0.0.1.

    Its geofence spans ``half_width_m`` around ``home`` and 2-120 m above it; system ids are 1..n.
    """
    if not 1 <= n <= 10:
        raise ValueError(f"n = {n}: a fleet has 1 to 10 vehicles")
    home = home or Home()
    lines = ["# A simulated fleet (uav-swarm vehicles): fly listens on these ports, the vehicles send there.",
             "[home]", f"lat_deg = {home.lat_deg!r}", f"lon_deg = {home.lon_deg!r}",
             f"alt_m = {home.alt_m!r}",
             "[geofence]", f"x_min_m = {-half_width_m!r}", f"x_max_m = {half_width_m!r}",
             f"y_min_m = {-half_width_m!r}", f"y_max_m = {half_width_m!r}", "alt_min_m = 2.0",
             "alt_max_m = 120.0"]
    for system_id in range(1, n + 1):
        lines += ["[[vehicles]]", f"system_id = {system_id}", f'url = "udpin:127.0.0.1:{free_udp_port()}"']
    return "\n".join(lines) + "\n"


class SimulatedFleet:
    """Simulated vehicles serving the endpoints of a bridge config (see the module docstring).

    Args:
        autopilot: ``"ardupilot"`` or ``"px4"``.
        bridge: The bridge config whose vehicles to serve (its ``[home]`` is the launch line's origin).
        n: Serve only its first ``n`` vehicles (default: all).
        spacing_m: Distance between neighbouring homes along the launch line (East).
        realism: Every vehicle's imperfections.
        params: Parameter values that differ from the autopilot's defaults, for every vehicle.
        failsafe: Set the link-loss failsafe to return home (ArduPilot ``FS_GCS_ENABLE`` 1, PX4
            ``NAV_DLL_ACT`` 2), as an operator prepares a vehicle; False: the autopilot's default (off).
        seed: Seeds the vehicles' random streams (vehicle ``i`` gets the ``i``-th child of it).
        prearm_s: Each vehicle refuses to arm this long after start.
    """

    def __init__(self, autopilot: str, bridge: BridgeConfig, *, n: int | None = None, spacing_m: float = 10.0,
                 realism: Realism | None = None, params: Mapping[str, float] | None = None,
                 failsafe: bool = True, seed: int = 0, prearm_s: float = 0.0) -> None:
        if autopilot not in AUTOPILOTS:
            raise ValueError(f"autopilot = {autopilot!r}: choose one of {sorted(AUTOPILOTS)}")
        endpoints = bridge.vehicles if n is None else bridge.vehicles[:n]
        if not endpoints or (n is not None and not 1 <= n <= len(bridge.vehicles)):
            raise ValueError(f"n = {n}: the bridge config has {len(bridge.vehicles)} vehicles; serve 1 to "
                             f"{len(bridge.vehicles)} of them")
        if not spacing_m > 0.0:
            raise ValueError(f"spacing_m = {spacing_m}: must be > 0")
        urls = [vehicle_url(endpoint.url) for endpoint in endpoints]  # all refused before any starts
        values = {**(_FAILSAFE[autopilot] if failsafe else {}), **(params or {})}
        kind = AUTOPILOTS[autopilot]
        rngs = np.random.default_rng(seed).spawn(len(endpoints))
        self.autopilot = autopilot
        self.vehicles: list[ArduCopter] = []
        try:
            for index, (endpoint, url) in enumerate(zip(endpoints, urls, strict=True)):
                home = launch_home(index, spacing_m, bridge.home)
                self.vehicles.append(kind(url, endpoint.system_id, home=home, realism=realism,
                                          rng=rngs[index], prearm_s=prearm_s, params=values))
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Stop every vehicle (their links close)."""
        for vehicle in self.vehicles:
            vehicle.close()

    def __enter__(self) -> SimulatedFleet:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.close()
