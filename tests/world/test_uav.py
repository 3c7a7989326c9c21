"""UAV kinematics: caps, bounds, waypoint arrival and the separation penalty."""

import numpy as np
import pytest

from uav_swarm.world.separation import separation_penalty
from uav_swarm.world.uav import UAVConfig, UAVFleet

CONFIG = UAVConfig(max_speed_m_s=8.0, max_accel_m_s2=3.0)


def test_speed_and_acceleration_caps():
    fleet = UAVFleet(np.full((3, 2), 50.0), CONFIG, 100.0, 100.0)
    rng = np.random.default_rng(0)
    for _ in range(200):
        before = fleet.velocities_m_s.copy()
        fleet.step(rng.uniform(-50, 50, size=(3, 2)), dt_s=0.1)
        speed = np.linalg.norm(fleet.velocities_m_s, axis=1)
        accel = np.linalg.norm(fleet.velocities_m_s - before, axis=1) / 0.1
        assert np.all(speed <= CONFIG.max_speed_m_s + 1e-9)
        assert np.all(accel <= CONFIG.max_accel_m_s2 + 1e-9)


def test_positions_stay_in_the_area():
    fleet = UAVFleet(np.array([[1.0, 1.0], [99.0, 50.0]]), CONFIG, 100.0, 60.0)
    for _ in range(100):
        fleet.step(np.array([[-8.0, -8.0], [8.0, 8.0]]), dt_s=0.1)
    assert fleet.positions_m.tolist() == [[0.0, 0.0], [100.0, 60.0]]
    assert np.all(fleet.velocities_m_s == 0.0)


def test_waypoints_are_reached_and_held():
    rng = np.random.default_rng(3)
    fleet = UAVFleet(rng.uniform(0, 200, size=(5, 2)), CONFIG, 200.0, 200.0)
    targets = rng.uniform(0, 200, size=(5, 2))
    for _ in range(600):
        fleet.step(fleet.waypoint_command(targets, 0.1), dt_s=0.1)
    assert np.allclose(fleet.positions_m, targets, atol=1e-3)
    assert np.allclose(fleet.velocities_m_s, 0.0, atol=1e-3)


def test_separation_penalty():
    assert separation_penalty(np.array([[0.0, 0.0], [10.0, 0.0]]), 5.0) == 0.0
    assert separation_penalty(np.array([[0.0, 0.0], [2.5, 0.0]]), 5.0) == pytest.approx(0.5)
    assert separation_penalty(np.zeros((3, 2)), 5.0) == pytest.approx(3.0)
    assert separation_penalty(np.zeros((3, 2)), 0.0) == 0.0
    assert separation_penalty(np.zeros((1, 2)), 5.0) == 0.0


def test_bad_positions_shape():
    with pytest.raises(ValueError, match="positions_m"):
        UAVFleet(np.zeros(4), CONFIG, 10.0, 10.0)
