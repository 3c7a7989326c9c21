"""Write ``pedsim_trajectories.npz``: the crowd's trajectories on the Pedsim scenes, as a reference.

Run from the repository root with the crowd code whose behaviour is the reference (see README.md):
``PYTHONPATH=$PWD python tests/data/crowd_reference/make_reference.py``. For each scene of ``SCENES`` it
builds ``CrowdSim(load_pedsim_xml(scene), CrowdConfig(), np.random.default_rng(SEED))``, steps it
``STEPS`` times and keeps, under the scene's stem (``scene1``, ``small_airport``):

- ``<stem>/positions_m``: ``(STEPS // EVERY + 1, N, 2)`` positions every ``EVERY`` steps, step 0 first;
- at every ``STATE_EVERY`` steps, the full state and the state one step later:
  ``<stem>/state_positions_m``, ``<stem>/state_velocities_m_s``, ``<stem>/state_route_position``
  (``(S, N, 2)``, ``(S, N, 2)``, ``(S, N)``) and ``<stem>/next_positions_m``, ``<stem>/next_velocities_m_s``.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

from uav_swarm.world.crowd import CrowdConfig, CrowdSim
from uav_swarm.world.pedsim import load_pedsim_xml

HERE = Path(__file__).resolve().parent
PEDSIM = HERE.parent / "pedsim"
SCENES = ("scene1.xml", "small_airport.xml")
SEED, STEPS, EVERY, STATE_EVERY = 0, 1000, 100, 200


def record(scene: Path) -> dict[str, np.ndarray]:
    """The arrays of one scene (keys without the scene prefix)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # queues, attractions and robots are not simulated
        sim = CrowdSim(load_pedsim_xml(scene), CrowdConfig(), np.random.default_rng(SEED))
    positions, states, nexts = [sim.positions_m], [], []
    for step in range(1, STEPS + 1):
        if (step - 1) % STATE_EVERY == 0:
            states.append((sim.positions_m, sim.velocities_m_s, sim._route_position.copy()))
        sim.step()
        if (step - 1) % STATE_EVERY == 0:
            nexts.append((sim.positions_m, sim.velocities_m_s))
        if step % EVERY == 0:
            positions.append(sim.positions_m)
    state_p, state_v, state_route = (np.stack(a) for a in zip(*states, strict=True))
    next_p, next_v = (np.stack(a) for a in zip(*nexts, strict=True))
    return {"positions_m": np.stack(positions), "state_positions_m": state_p, "state_velocities_m_s": state_v,
            "state_route_position": state_route, "next_positions_m": next_p, "next_velocities_m_s": next_v}


def main() -> None:
    arrays = {}
    for name in SCENES:
        for key, value in record(PEDSIM / name).items():
            arrays[f"{Path(name).stem}/{key}"] = value
    out = HERE / "pedsim_trajectories.npz"
    tmp = out.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, **arrays)
    tmp.replace(out)
    print(f"wrote {out.name}: {', '.join(f'{k} {v.shape}' for k, v in arrays.items())}", file=sys.stderr)


if __name__ == "__main__":
    main()
