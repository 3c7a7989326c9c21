"""Helpers of the ROS 2 tests: a domain of their own and the peer process (under strace when asked)."""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from traffic import strace_prefix

REPO = Path(__file__).resolve().parents[1]
PEER = Path(__file__).resolve().parent / "ros2_peer.py"
_DOMAINS = itertools.count()


def domain_id() -> int:
    """A ROS_DOMAIN_ID of this test (1..100), apart from other tests and other test processes."""
    return 1 + (os.getpid() * 7 + 13 * next(_DOMAINS)) % 100


def start_peer(spec: dict, out: Path, env: dict[str, str], trace: Path | None = None) -> subprocess.Popen:
    """Start the ROS 2 peer (``tests/ros2_peer.py``) and wait until its subscriptions exist."""
    spec_path = out.with_suffix(".spec.json")
    spec_path.write_text(json.dumps(spec))
    command = [sys.executable, str(PEER), str(spec_path), str(out)]
    peer = subprocess.Popen((strace_prefix(trace) if trace else []) + command, env=env)
    ready = Path(str(out) + ".ready")
    deadline = time.monotonic() + 120.0
    while not ready.exists() and peer.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert ready.exists(), "the ROS 2 peer did not start"
    return peer


def ros_env(domain: int) -> dict[str, str]:
    """This process's environment for a child: the worktree first on the path, its own ROS domain."""
    return {**os.environ, "ROS_DOMAIN_ID": str(domain),
            "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
