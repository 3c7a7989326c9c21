"""One implementation of the environment's logic: the shells (raw_env, BatchedUAVSwarm, the vector view)
hold none of it and call the core, which calls the world's models.

Two proofs: the shells' source computes nothing (no numeric kernel, no function of the core's names), and
replacing a core function at its one definition changes what every shell returns.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import uav_swarm.env.core as core_module
from uav_swarm.env.batched import BatchedUAVSwarm
from uav_swarm.env.parallel import parallel_env
from uav_swarm.env.vector import UAVSwarmVectorEnv

REPO = Path(__file__).resolve().parents[2]
SHELLS = ("uav_swarm/env/parallel.py", "uav_swarm/env/batched.py", "uav_swarm/env/vector.py")
# The logic and where it lives, once: observation, reward, infos, controller, kinematics, coverage,
# separation.
ONE_HOME = {
    "observe": "uav_swarm/env/observe.py",
    "team_reward": "uav_swarm/env/observe.py",
    "info_arrays": "uav_swarm/env/observe.py",
    "waypoint_velocity": "uav_swarm/world/uav.py",
    "fly_step": "uav_swarm/world/uav.py",
    "coverage_batch": "uav_swarm/world/comms_batch.py",
    "evaluate_coverage": "uav_swarm/world/comms.py",
    "separation_penalty": "uav_swarm/world/separation.py",
    "closest_distances_m": "uav_swarm/world/separation.py",
    "density_maps": "uav_swarm/world/raster.py",
}
# What computing the world looks like in numpy: none of it may appear in a shell.
KERNELS = {"bincount", "einsum", "exp", "hypot", "sqrt", "argmin", "sliding_window_view", "clip", "minimum"}
WORLD = {"scenario": {"n_groups_min": 1, "n_groups_max": 1, "group_size_min": 8, "group_size_max": 8},
         "density_shape": (16, 16), "patch_px": 3, "n_uavs": 3, "action_mode": "waypoint", "max_cycles": 5}


def _definitions() -> dict[str, list[str]]:
    found: dict[str, list[str]] = {}
    for path in sorted((REPO / "uav_swarm").rglob("*.py")):
        for node in ast.parse(path.read_text()).body:  # module-level functions (methods have other names)
            name = getattr(node, "name", "").lstrip("_")
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and name in ONE_HOME:
                found.setdefault(name, []).append(str(path.relative_to(REPO)))
    return found


def test_each_piece_of_logic_is_defined_once_where_it_belongs():
    assert _definitions() == {name: [home] for name, home in ONE_HOME.items()}


@pytest.mark.parametrize("shell", SHELLS)
def test_shells_compute_nothing(shell):
    tree = ast.parse((REPO / shell).read_text())
    called = {node.func.attr for node in ast.walk(tree)
              if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)}
    assert not called & KERNELS, f"{shell} computes {sorted(called & KERNELS)} itself"
    imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert not {m for m in imported if m and m.startswith("uav_swarm.world.")} - {"uav_swarm.world.scenario",
                                                                                   "uav_swarm.world.comms",
                                                                                   "uav_swarm.world.crowd_batch"}


def _outputs():
    """Observations, rewards and infos of the three shells after a reset and one step."""
    single = parallel_env(**WORLD)
    obs, _ = single.reset(seed=0)
    targets = {a: np.array([50.0, 60.0]) for a in single.agents}
    obs, rewards, _, _, infos = single.step(targets)
    batch = BatchedUAVSwarm(2, **WORLD)
    batch.reset(seed=0)
    b_obs, b_rew, _, _, b_info = batch.step(np.full((2, 3, 2), [50.0, 60.0]))
    vector = UAVSwarmVectorEnv(2, **WORLD)
    vector.reset(seed=0)
    v_obs, v_rew, _, _, v_info = vector.step(np.full((2, 3, 2), [50.0, 60.0]))
    return {"single": (obs["uav_0"][:4], rewards["uav_0"], infos["uav_0"]["users_served"]),
            "batched": (b_obs[0, 0, :4], b_rew[0], b_info["users_served"][0, 0]),
            "vector": (v_obs[0, 0, :4], v_rew[0], v_info["users_served"][0, 0])}


@pytest.mark.parametrize(("name", "replacement", "changed"), [
    ("observe", lambda real: lambda *a: real(*a) * 0.0 + 0.25, 0),
    ("team_reward", lambda real: lambda *a: real(*a) * 0.0 - 7.0, 1),
    ("waypoint_velocity", lambda real: lambda *a: real(*a) * 0.0, 0),
    ("coverage_batch", lambda real: lambda *a: _no_users_served(real(*a)), 2),
])
def test_replacing_the_one_definition_changes_every_shell(monkeypatch, name, replacement, changed):
    before = _outputs()
    monkeypatch.setattr(core_module, name, replacement(getattr(core_module, name)))
    after = _outputs()
    for shell in before:
        assert not np.array_equal(before[shell][changed], after[shell][changed]), (shell, name)


def _no_users_served(coverage):
    import dataclasses

    return dataclasses.replace(coverage, users_per_uav=coverage.users_per_uav + 1000)
