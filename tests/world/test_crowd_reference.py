"""The crowd against trajectories recorded from the code before its pair forces were compiled.

``tests/data/crowd_reference/`` (its README says how the file was made and what it can show): one step
from each recorded state must give the recorded next state to the last bits, and whole trajectories
must stay within 1e-9 m of the recorded ones for as long as a last-bit change of one force does.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from uav_swarm.world.crowd import CrowdConfig, CrowdSim
from uav_swarm.world.crowd_batch import BatchedCrowd
from uav_swarm.world.pedsim import load_pedsim_xml

DATA = Path(__file__).resolve().parents[1] / "data"
SCENES = ("scene1", "small_airport")
EVERY = 100  # steps between recorded positions
# Steps for which the old code itself, summing the same forces in another order, stays within 1e-9 m of
# the file (README): beyond, the crowd's chaos turns last-bit differences into centimetres.
EQUAL_FOR_STEPS = {"scene1": 500, "small_airport": 1000}


@pytest.fixture(scope="module")
def reference():
    with np.load(DATA / "crowd_reference" / "pedsim_trajectories.npz") as data:
        return {key: data[key] for key in data.files}


def _crowd(scene: str) -> CrowdSim:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # queues, attractions and robots are not simulated
        scenario = load_pedsim_xml(DATA / "pedsim" / f"{scene}.xml")
    return CrowdSim(scenario, CrowdConfig(), np.random.default_rng(0))


def _set_state(sim: CrowdSim, reference: dict, scene: str, k: int) -> None:
    sim._positions = reference[f"{scene}/state_positions_m"][k]
    sim._velocities = reference[f"{scene}/state_velocities_m_s"][k]
    sim._route_position = reference[f"{scene}/state_route_position"][k].copy()


@pytest.mark.parametrize("scene", SCENES)
def test_trajectories_follow_the_recorded_ones(reference, scene):
    sim = _crowd(scene)
    recorded = reference[f"{scene}/positions_m"]
    np.testing.assert_array_equal(sim.positions_m, recorded[0])  # same spawn
    for k in range(1, EQUAL_FOR_STEPS[scene] // EVERY + 1):
        sim.step(EVERY)
        np.testing.assert_allclose(sim.positions_m, recorded[k], rtol=0, atol=1e-9,
                                   err_msg=f"step {k * EVERY}")


@pytest.mark.parametrize("batched", [False, True], ids=["alone", "batched"])
def test_one_step_from_every_recorded_state_gives_the_recorded_next_state(reference, batched):
    for scene in SCENES:
        for k in range(len(reference[f"{scene}/state_positions_m"])):
            sim = _crowd(scene)
            _set_state(sim, reference, scene, k)
            if batched:  # the scene between two other crowds, which must not disturb it
                crowd = BatchedCrowd([_crowd("small_airport"), sim, _crowd("scene1")])
                crowd.step()
                s = slice(crowd.offsets[1], crowd.offsets[2])
                positions, velocities = crowd.positions_m[s], crowd.velocities_m_s[s]
            else:
                sim.step()
                positions, velocities = sim.positions_m, sim.velocities_m_s
            for got, key in ((positions, "next_positions_m"), (velocities, "next_velocities_m_s")):
                np.testing.assert_allclose(got, reference[f"{scene}/{key}"][k], rtol=0, atol=1e-12,
                                           err_msg=f"{scene}, state {k}")
