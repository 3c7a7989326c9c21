"""The social-force crowd: hard walls, speed caps, determinism, progress and cohesion."""

import warnings
from pathlib import Path

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.world.crowd import CrowdConfig, CrowdSim
from uav_swarm.world.pedsim import load_pedsim_xml
from uav_swarm.world.scenario import (
    AgentGroup,
    Scenario,
    ScenarioConfig,
    Waypoint,
    random_scenario,
)

PEDSIM = Path(__file__).resolve().parents[1] / "data" / "pedsim"


def _crossings(start, end, segments):
    """Number of (move, segment) pairs that intersect, touching included (orientation test)."""
    if not len(segments):
        return 0
    p, q = start[:, None, :], end[:, None, :]
    a, b = segments[None, :, :2], segments[None, :, 2:]

    def orient(u, v, w):
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (
            w[..., 0] - u[..., 0]
        )

    hit = (orient(p, q, a) * orient(p, q, b) <= 0) & (orient(a, b, p) * orient(a, b, q) <= 0)
    moved = np.any(start != end, axis=1)[:, None]
    return int((hit & moved).sum())


def _pedsim(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_pedsim_xml(PEDSIM / name)


SMALL = ScenarioConfig(
    width_m=120.0,
    height_m=120.0,
    n_obstacles=12,
    n_waypoints=5,
    waypoint_separation_m=25.0,
    n_groups_min=4,
    n_groups_max=5,
)


def _random(seed=3):
    return random_scenario(np.random.default_rng(seed), SMALL)


def _wall_distance(points, segments):
    """Smallest distance from any point to any segment."""
    a, d = segments[None, :, :2], segments[None, :, 2:] - segments[None, :, :2]
    r = points[:, None, :] - a
    t = np.clip((r * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-12), 0.0, 1.0)
    return float(np.linalg.norm(r - t[..., None] * d, axis=-1).min())


def _check_invariants(sim, n_steps):
    """Step ``n_steps`` times asserting the invariants; return the closest approach to an obstacle."""
    s = sim.scenario
    closest = np.inf
    for _ in range(n_steps):
        before = sim.positions_m
        sim.step()
        after = sim.positions_m
        assert _crossings(before, after, s.obstacles) == 0
        assert (after > 0).all() and (after[:, 0] < s.width_m).all() and (after[:, 1] < s.height_m).all()
        speed = np.hypot(*sim.velocities_m_s.T)
        assert (speed <= sim.max_speeds_m_s * (1 + 1e-12)).all()
        np.testing.assert_allclose(after - before, sim.velocities_m_s * sim.dt_s, atol=1e-12)
        if len(s.obstacles):
            closest = min(closest, _wall_distance(after, s.obstacles))
    return closest


@pytest.mark.parametrize(
    "make",
    [_random, lambda: _pedsim("scene1.xml"), lambda: _pedsim("small_airport.xml")],
    ids=["random", "pedsim-scene1", "pedsim-airport"],
)
def test_walls_speeds_and_bounds_hold(make):
    scenario = make()
    sim = CrowdSim(scenario, CrowdConfig(), np.random.default_rng(0))
    assert sim.positions_m.shape == (scenario.n_pedestrians, 2)
    _check_invariants(sim, 300)
    assert sim.time_s == pytest.approx(30.0)


def test_walls_hold_against_huge_forces():
    """Fast walkers pushed hard into a comb of walls without wall repulsion: only hard walls stop them."""
    teeth = [[x, 5.0, x, 35.0] for x in np.arange(6.0, 40.0, 2.0)]
    zigzag = [[40.0 + 2 * k, 5.0, 41.0 + 2 * k, 35.0] for k in range(5)]
    obstacles = np.array(teeth + zigzag + [[1.0, 20.0, 39.0, 20.0]])
    scenario = Scenario(
        60.0,
        40.0,
        obstacles,
        (Waypoint("east", 58.0, 20.0, 1.0), Waypoint("west", 2.0, 20.0, 1.0)),
        (
            AgentGroup(3.0, 20.0, 4.0, 30.0, 150, ("east", "west")),
            AgentGroup(55.0, 20.0, 6.0, 30.0, 150, ("west",)),
        ),
    )
    config = CrowdConfig(
        dt_s=0.5,
        relaxation_time_s=0.5,
        desired_speed_mean_m_s=2.8,
        desired_speed_min_m_s=2.5,
        desired_speed_max_m_s=3.0,
        max_speed_factor=3.0,
        max_speed_m_s=9.0,
        obstacle_repulsion_m_s2=0.0,
        ped_repulsion_m_s2=60.0,
        group_cohesion_m_s2=20.0,
    )
    sim = CrowdSim(scenario, config, np.random.default_rng(1))
    assert _check_invariants(sim, 150) < 0.05  # they were pressed against the walls


def test_same_seed_same_trajectories():
    scenario = _random(5)
    runs = []
    for seed in (11, 11, 12):
        sim = CrowdSim(scenario, CrowdConfig(), np.random.default_rng(seed))
        trajectory = [sim.positions_m]
        for _ in range(20):
            sim.step(10)
            trajectory.append(sim.positions_m)
        runs.append(np.stack(trajectory))
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])


def test_pedestrians_go_around_a_wall_to_reach_their_waypoint():
    wall = np.array([[30.0, 5.0, 30.0, 55.0]])  # hides the goal; the way round is 5 m from either end
    scenario = Scenario(
        60.0,
        60.0,
        wall,
        (Waypoint("goal", 50.0, 30.0, 3.0),),
        (AgentGroup(15.0, 30.0, 10.0, 10.0, 40, ("goal",)),),
    )
    sim = CrowdSim(scenario, CrowdConfig(), np.random.default_rng(2))
    sim.step(900)
    assert (sim.waypoints_reached >= 1).all()


@pytest.mark.parametrize("make", [_random, lambda: _pedsim("scene1.xml")], ids=["random", "pedsim-scene1"])
def test_crowd_makes_progress_along_routes(make):
    sim = CrowdSim(make(), CrowdConfig(), np.random.default_rng(0))
    sim.step(600)
    before = sim.positions_m
    sim.step(300)
    assert (sim.waypoints_reached >= 1).mean() >= 0.75
    assert sim.waypoints_reached.mean() >= 1.0
    moved = np.linalg.norm(sim.positions_m - before, axis=1)
    # nobody jams: in 30 s nearly everyone got somewhere (one realisation of a chaotic crowd: a change in
    # the last bit of a force moves this share by a few percent, 0.94 to 0.98 over spawn seeds 0 to 3)
    assert (moved >= 5.0).mean() >= 0.9


def _spread(sim):
    g = sim.group_ids
    return np.array(
        [
            np.sqrt(((sim.positions_m[g == k] - sim.positions_m[g == k].mean(0)) ** 2).sum(1).mean())
            for k in range(len(sim.scenario.groups))
        ]
    )


def test_groups_stay_cohesive():
    scenario = _random(1)
    together = CrowdSim(scenario, CrowdConfig(), np.random.default_rng(0))
    apart = CrowdSim(
        scenario,
        CrowdConfig(group_cohesion_m_s2=0.0, desired_speed_group_correlation=0.0),
        np.random.default_rng(0),
    )
    together.step(900)
    apart.step(900)
    sizes = np.array([g.size for g in scenario.groups])
    assert (_spread(together) < 3.0 * 0.7 * np.sqrt(sizes)).all()
    assert _spread(together).mean() < 0.7 * _spread(apart).mean()


def test_group_without_route_stands_still_and_coincident_spawns_separate():
    scenario = Scenario(20.0, 20.0, np.zeros((0, 4)), (), (AgentGroup(10.0, 10.0, 0.0, 0.0, 5, ()),))
    sim = CrowdSim(scenario, CrowdConfig(), np.random.default_rng(0))
    assert np.ptp(sim.positions_m, axis=0).max() == 0.0
    sim.step(100)
    p = sim.positions_m
    assert np.isfinite(p).all()
    assert np.linalg.norm(p - [10.0, 10.0], axis=1).max() < 2.0
    assert np.min([np.linalg.norm(p[i] - p[j]) for i in range(5) for j in range(i + 1, 5)]) > 0.3
    assert np.abs(sim.velocities_m_s).max() < 0.05


def test_spawn_keeps_clear_of_walls():
    scenario = _pedsim("scene1.xml")
    config = CrowdConfig(spawn_clearance_m=0.8)
    sim = CrowdSim(scenario, config, np.random.default_rng(0))
    p, s = sim.positions_m, scenario.obstacles
    t = np.linspace(0.0, 1.0, 1001)
    samples = (s[:, None, :2] + t[None, :, None] * (s[:, None, 2:] - s[:, None, :2])).reshape(-1, 2)
    nearest = np.array([np.linalg.norm(samples - q, axis=1).min() for q in p])
    assert nearest.min() >= 0.8 - 0.1
    for k, g in enumerate(scenario.groups):
        x0, y0, x1, y1 = g.spawn_rectangle_m
        q = p[sim.group_ids == k]
        assert len(q) == g.size
        assert ((q[:, 0] >= x0) & (q[:, 0] <= x1) & (q[:, 1] >= y0) & (q[:, 1] <= y1)).all()


def test_spawn_area_inside_a_wall_band_raises():
    scenario = Scenario(
        20.0, 20.0, np.array([[10.0, 0.0, 10.0, 20.0]]), (), (AgentGroup(10.0, 10.0, 0.2, 0.2, 3, ()),)
    )
    with pytest.raises(ValueError, match=r"groups\[0\].*spawn"):
        CrowdSim(scenario, CrowdConfig(), np.random.default_rng(0))


def test_state_is_read_only_and_snapshots_stay_valid():
    sim = CrowdSim(_random(), CrowdConfig(), np.random.default_rng(0))
    kept = sim.positions_m
    copy = kept.copy()
    with pytest.raises(ValueError):
        sim.positions_m[0, 0] = 1.0
    with pytest.raises(ValueError):
        sim.velocities_m_s[0, 0] = 1.0
    sim.step(5)
    np.testing.assert_array_equal(kept, copy)
    assert not np.array_equal(sim.positions_m, copy)


def test_empty_crowd_steps():
    sim = CrowdSim(Scenario(10.0, 10.0, np.zeros((0, 4)), (), ()), CrowdConfig(), np.random.default_rng(0))
    sim.step(3)
    assert sim.positions_m.shape == (0, 2) and sim.time_s == pytest.approx(0.3)


@pytest.mark.parametrize("n_steps", [-1, 1.5, True, "2"])
def test_step_rejects_bad_counts(n_steps):
    sim = CrowdSim(_random(), CrowdConfig(), np.random.default_rng(0))
    with pytest.raises(ValueError, match="n_steps"):
        sim.step(n_steps)


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"dt_s": 0.0}, "dt_s"),
        ({"relaxation_time_s": -1.0}, "relaxation_time_s"),
        ({"desired_speed_std_m_s": 2.0}, "desired_speed_std_m_s"),
        ({"desired_speed_min_m_s": 1.5}, "desired_speed_min_m_s"),
        ({"desired_speed_max_m_s": 3.0, "max_speed_m_s": 2.0}, "max_speed_m_s"),
        ({"dt_s": 0.6}, "relaxation_time_s"),
        ({"neighbour_cutoff_m": 0.0}, "neighbour_cutoff_m"),
        ({"desired_speed_group_correlation": 1.5}, "desired_speed_group_correlation"),
    ],
    ids=[
        "dt",
        "relaxation",
        "std",
        "min-above-mean",
        "cap-below-desired",
        "dt-above-relaxation",
        "cutoff",
        "correlation",
    ],
)
def test_crowd_config_rejects_bad_values(changes, field):
    with pytest.raises(ConfigError, match=field):
        CrowdConfig(**changes)


def test_crowd_config_rejects_unknown_keys():
    with pytest.raises(ConfigError, match="dt"):
        CrowdConfig.from_dict({"dt": 0.1})


def test_desired_speeds_follow_the_configured_distribution():
    scenario = Scenario(
        200.0,
        200.0,
        np.zeros((0, 4)),
        (),
        tuple(AgentGroup(100.0, 100.0, 150.0, 150.0, 100, ()) for _ in range(40)),
    )
    sim = CrowdSim(scenario, CrowdConfig(), np.random.default_rng(0))
    v0 = sim.desired_speeds_m_s
    assert abs(v0.mean() - 1.34) < 0.05 and abs(v0.std() - 0.26) < 0.04
    assert v0.min() >= 0.5 and v0.max() <= 2.0
    np.testing.assert_allclose(sim.max_speeds_m_s, np.minimum(1.3 * v0, 2.5))
