"""The ``[ros2]`` table of ``simulate`` and ``fly``, and the environment a ROS 2 node of the project runs in.

ROS 2 reads its settings from the process environment when the first node is made. Unless told
otherwise the project keeps DDS on this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``: discovery
and data to 127.0.0.1 only, no multicast) and picks the one middleware the ``ros2`` extra installs
(``rmw_fastrtps_cpp``). ``ROS_DOMAIN_ID`` is the user's, as everywhere in ROS 2. The wheels' shared
libraries are found by the wheels themselves: nothing needs sourcing.

Examples:
    >>> Ros2Config(enabled=True).namespace_for("demo-1")
    '/uav_swarm/demo_1'
    >>> env = {}
    >>> ros2_environment(Ros2Config(), env)["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    'LOCALHOST'
    >>> Ros2Config(namespace="bad name")
    Traceback (most recent call last):
    ...
    typed_config.ConfigError: Ros2Config.namespace = 'bad name': '/' then names of A-Z a-z 0-9 _
"""

from __future__ import annotations

import os
import re
from collections.abc import MutableMapping
from dataclasses import dataclass
from types import ModuleType

from typed_config import Config, ConfigError, param

__all__ = ["Ros2Config", "ros2_environment", "import_rclpy", "MISSING_EXTRA", "RMW_IMPLEMENTATION"]

RMW_IMPLEMENTATION = "rmw_fastrtps_cpp"
"""The ROS 2 middleware the ``ros2`` extra installs (Fast DDS)."""

MISSING_EXTRA = "ROS 2 is not installed: pip install 'uav-swarm[ros2]'"
"""What a run that asks for ROS 2 says when the ``ros2`` extra is missing."""

_NAMESPACE = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)+$")


@dataclass(frozen=True)
class Ros2Config(Config):
    """ROS 2 topics of a run (``--ros2``): where they live, how fast, and how DDS discovers."""

    enabled: bool = param(False, doc="publish the run on ROS 2 and take operator targets (--ros2)")
    namespace: str = param("", doc="topic namespace (empty: /uav_swarm/<telemetry.swarm>, '-' as '_')")
    localhost_only: bool = param(
        True, doc="keep DDS on this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST); false: the "
        "environment's discovery range (ROS 2's default reaches the subnet)")
    speed: float = param(0.0, ge=0.0, le=1000.0,
                         doc="simulate: simulated seconds per wall-clock second (0: as fast as it computes)")
    markers_max_rate_hz: float = param(
        10.0, ge=0.0, le=1000.0, doc="most marker arrays per wall-clock second (0: one per published step); "
        "an unpaced simulate publishes hundreds of steps a second, more than a viewer draws")
    wait_for_subscriber_s: float = param(
        0.0, ge=0.0, le=600.0, doc="wait this long for a ROS 2 subscriber of the poses before the first step")

    def check(self) -> None:
        """The namespace is a ROS 2 name."""
        if self.namespace and not _NAMESPACE.match(self.namespace):
            raise ConfigError(f"Ros2Config.namespace = {self.namespace!r}: '/' then names of A-Z a-z 0-9 _")

    def namespace_for(self, swarm: str) -> str:
        """The namespace of the swarm's topics: the configured one, else ``/uav_swarm/<swarm>``."""
        return self.namespace or "/uav_swarm/" + re.sub(r"[^A-Za-z0-9_]", "_", swarm)


def ros2_environment(config: Ros2Config, environ: MutableMapping[str, str] | None = None
                     ) -> MutableMapping[str, str]:
    """Set what ROS 2 reads from the environment (before the first node); returns ``environ``.

    Args:
        config: ``localhost_only`` sets the discovery range to this machine, whatever it was.
        environ: The environment to set (default ``os.environ``, the one ROS 2 reads).
    """
    environ = os.environ if environ is None else environ
    environ.setdefault("RMW_IMPLEMENTATION", RMW_IMPLEMENTATION)
    if config.localhost_only:
        environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        environ.pop("ROS_STATIC_PEERS", None)  # peers elsewhere would be reached despite the range
    return environ


def import_rclpy() -> ModuleType:
    """``rclpy``, or a :class:`ConfigError` that names the ``ros2`` extra when it is not installed.

    Raises:
        ConfigError: :data:`MISSING_EXTRA`; or rclpy is there but its libraries do not load (e.g. Python
            started with ``-S``, which skips the wheels' start-up hook that sets their library path).
    """
    try:
        import rclpy
    except ImportError as exc:
        if isinstance(exc, ModuleNotFoundError) and exc.name in ("rclpy", None):
            raise ConfigError(MISSING_EXTRA) from exc
        first_line = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise ConfigError(f"ROS 2 (rclpy) is installed but does not load: {first_line}; reinstall "
                          "'uav-swarm[ros2]' and start Python without -S") from exc
    return rclpy
