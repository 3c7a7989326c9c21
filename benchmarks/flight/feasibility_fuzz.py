"""Do the fleet check, the env's start positions and the separation of targets agree? A fuzz of fleets.

Each case draws a fleet (2-10 UAVs), an area (sides 8-200 m) and a minimum near the edge of what the rule
allows (0.8-1.1 times :func:`uav_swarm.world.separation.max_spread_m`), then asks all three:

- the fleet check: ``EnvConfig`` (``[uav] min_separation_m``, ``[scenario]`` area; its check is
  :func:`uav_swarm.world.separation.check_fleet_fits`) accepts or refuses with a ``ConfigError`` naming
  the field;
- the env: ``parallel_env(...).reset(seed)`` of the accepted configs (a scenario of one small group, no
  obstacles, so that tiny areas have a crowd) starts the UAVs inside the area, every pair at least the
  minimum apart; a refused minimum is given straight to the start positions' draw
  (:func:`uav_swarm.world.separation.draw_apart_m`, what ``reset`` calls), which must refuse it too;
- the targets: :func:`uav_swarm.planning.spacing.separate_targets` of random targets (pulled onto one or
  two groups) must return targets inside the area at least the minimum apart, or refuse.

The judge is ``scipy.spatial.distance.pdist``. Exit 1 on any disagreement. With ``PYTHONPATH`` set to an
older checkout, the same cases judge its rule.

Usage: python benchmarks/flight/feasibility_fuzz.py [--cases 1000] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
from scipy.spatial.distance import pdist

from typed_config import ConfigError
from uav_swarm.env.config import EnvConfig
from uav_swarm.env.parallel import parallel_env
from uav_swarm.planning.spacing import separate_targets
from uav_swarm.world.separation import draw_apart_m, max_spread_m, required_distances_m

SMALL_SCENE = {"n_obstacles": 0, "obstacle_length_min_m": 1.0, "obstacle_length_max_m": 2.0, "n_waypoints": 1,
               "waypoint_radius_m": 1.0, "waypoint_separation_m": 0.0, "n_groups_min": 1, "n_groups_max": 1,
               "group_size_min": 5, "group_size_max": 5, "route_length_min": 1, "route_length_max": 1,
               "spawn_extent_m": 1.0, "margin_m": 0.0, "clearance_m": 0.0}


def run_case(rng: np.random.Generator, seed: int) -> dict[str, bool]:
    """One fleet: what each of the three said, and whether what it returned was separated."""
    n = int(rng.integers(2, 11))
    area = rng.uniform(8.0, 200.0, 2)
    minimum = round(max_spread_m(n, *area) * float(rng.uniform(0.8, 1.1)), 3)
    scene = {**SMALL_SCENE, "width_m": float(area[0]), "height_m": float(area[1])}
    try:
        config = EnvConfig.from_dict({"n_uavs": n, "uav": {"min_separation_m": minimum}, "scenario": scene})
        check = True
    except ConfigError as error:
        assert "uav.min_separation_m" in str(error), error
        check = False
    if check:
        env = parallel_env(config=config)
        try:
            env.reset(seed=seed)
        except ValueError:  # an older rule: accepted by the check, not started
            return {"check": True, "reset": False, "spacing": True, "reset_ok": False, "spacing_ok": True}
        start = np.asarray(env.uav_positions_m)
        reset, reset_ok = True, bool(pdist(start).min() >= minimum - 1e-9
                                     and np.all((start >= 0.0) & (start <= area)))
    else:
        try:
            draw_apart_m(rng, n, area, required_distances_m(minimum, None, n))
            reset, reset_ok = True, False
        except ValueError:  # ConfigError is one
            reset, reset_ok = False, True
    groups = rng.uniform(0.0, area, (2, 2))
    wanted = np.clip(groups[rng.integers(0, 2, n)] + rng.normal(0.0, minimum / 3.0, (n, 2)), 0.0, area)
    try:
        targets = separate_targets(wanted, minimum, rng.permutation(n), area)
        spacing, spacing_ok = True, bool(pdist(targets).min() >= minimum - 1e-9
                                         and np.all((targets >= 0.0) & (targets <= area)))
    except ConfigError:
        spacing, spacing_ok = False, True
    return {"check": check, "reset": reset, "spacing": spacing, "reset_ok": reset_ok,
            "spacing_ok": spacing_ok}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs; load average at start {os.getloadavg()}")
    rng = np.random.default_rng(args.seed)
    start = time.perf_counter()
    accepted = disagree = unseparated = 0
    for case in range(args.cases):
        said = run_case(rng, args.seed * 100_000 + case)
        accepted += said["check"]
        disagree += not (said["check"] == said["reset"] == said["spacing"])
        unseparated += not (said["reset_ok"] and said["spacing_ok"])
    print(f"{args.cases} fleets (2-10 UAVs, sides 8-200 m, minimum 0.8-1.1 x the rule's limit) in "
          f"{time.perf_counter() - start:.0f} s: accepted {accepted}, refused {args.cases - accepted}")
    print(f"check / reset / separate_targets disagree: {disagree}; accepted but not separated: {unseparated}")
    print(f"load average at end {os.getloadavg()}")
    raise SystemExit(1 if disagree or unseparated else 0)


if __name__ == "__main__":
    main()
