"""``python -m uav_swarm``: the ``uav-swarm`` command without its console script."""

import sys

from uav_swarm.cli import main

sys.exit(main())
