"""uav-swarm: place and fly a swarm of up to 10 UAVs over a moving crowd.

Importing the package points numba's on-disk cache of compiled kernels at the user's cache folder
(``$XDG_CACHE_HOME/uav-swarm/numba``, by default ``~/.cache/uav-swarm/numba``; the platform's cache
folder on macOS and Windows) unless ``NUMBA_CACHE_DIR`` is set: never into the installed package.
"""

import os
import sys
from pathlib import Path

__version__ = "0.2.0"


def user_cache_dir() -> Path:
    """This user's cache folder of uav-swarm (it need not exist yet)."""
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "uav-swarm"


os.environ.setdefault("NUMBA_CACHE_DIR", str(user_cache_dir() / "numba"))
if "numba" in sys.modules:  # imported before us: it read its settings already
    sys.modules["numba"].config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]
