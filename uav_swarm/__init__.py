"""uav-swarm: place and fly a swarm of up to 10 UAVs over a moving crowd.

Importing the package, before any of its modules loads a third-party library:

- keeps every library's usage reporting off (:data:`TELEMETRY_OFF`, set in the process environment,
  where the libraries read it when they load, and where every process a run starts inherits it);
  a value the user set is kept: ``ORT_DISABLE_TELEMETRY=0`` in the shell is how a user opts in;
- points numba's on-disk cache of compiled kernels at the user's cache folder
  (``$XDG_CACHE_HOME/uav-swarm/numba``, by default ``~/.cache/uav-swarm/numba``; the platform's cache
  folder on macOS and Windows) unless ``NUMBA_CACHE_DIR`` is set: never into the installed package.

What the libraries would send without it: ONNX Runtime (the ``inference`` extra) resolves and posts usage
events to Microsoft's OneCollector (``mobile.events.data.microsoft.com``) about 10 s after a session
starts, unless ``ORT_DISABLE_TELEMETRY=1`` is set before it is imported (its
``disable_telemetry_events()`` does not stop it); Ray (the ``distributed`` extra) reports usage statistics
when a cluster starts unless ``RAY_USAGE_STATS_ENABLED=0``. Checked and silent without a setting: torch
(``torch.hub`` downloads only when called), the Foxglove SDK (its server binds where it is told; remote
access only with a device token), numba, matplotlib. The project's own traffic stays on loopback by its
settings: Zenoh without multicast scouting, DDS with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless
``[ros2] localhost_only = false``, MAVLink to the endpoints a bridge config names.

Examples:
    >>> env = {"RAY_USAGE_STATS_ENABLED": "1"}  # the user's own choice stays
    >>> telemetry_off(env) == {"ORT_DISABLE_TELEMETRY": "1", "RAY_USAGE_STATS_ENABLED": "1"}
    True

May import: ``typed_config``, ``learning``, ``bridge``.
"""

import os
import sys
from collections.abc import MutableMapping
from pathlib import Path

__version__ = "0.2.0"

TELEMETRY_OFF: dict[str, str] = {
    "ORT_DISABLE_TELEMETRY": "1",  # ONNX Runtime: no OneCollector usage events
    "RAY_USAGE_STATS_ENABLED": "0",  # Ray: no usage statistics
}
"""The environment variables that keep each library's usage reporting off, and their values."""


def telemetry_off(environ: MutableMapping[str, str] | None = None) -> MutableMapping[str, str]:
    """Set each of :data:`TELEMETRY_OFF` the user has not set in ``environ`` (default ``os.environ``)."""
    environ = os.environ if environ is None else environ
    for name, value in TELEMETRY_OFF.items():
        environ.setdefault(name, value)
    return environ


def user_cache_dir() -> Path:
    """This user's cache folder of uav-swarm (it need not exist yet)."""
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "uav-swarm"


telemetry_off()
os.environ.setdefault("NUMBA_CACHE_DIR", str(user_cache_dir() / "numba"))
if "numba" in sys.modules:  # imported before us: it read its settings already
    sys.modules["numba"].config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]
