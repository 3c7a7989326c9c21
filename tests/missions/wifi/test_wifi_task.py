from pathlib import Path

import numpy as np
import pytest

from learning.task import MAX_POSITIONS, Task
from typed_config import ConfigError
from uav_swarm.missions.registry import make_task, task_factory
from uav_swarm.missions.wifi.exact import exact_placement
from uav_swarm.missions.wifi.expert import WifiExpertConfig, place_uavs
from uav_swarm.missions.wifi.rules import assign_users, candidate_grid, squared_distances
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask, coverage_rules, crowd_raster
from uav_swarm.world.comms import RadioConfig, evaluate_coverage
from uav_swarm.world.scenario import ScenarioConfig

REPO = Path(__file__).resolve().parents[3]
SMALL_SCENARIO = ScenarioConfig(n_groups_min=4, n_groups_max=5)


def _blob(rng: np.random.Generator, centre: tuple[float, float], n: int, spread_m: float = 3.0) -> np.ndarray:
    return np.asarray(centre) + rng.normal(0.0, spread_m, size=(n, 2))


@pytest.fixture(scope="module", params=[1, 2], ids=["s1", "s2"])
def task(request):
    return WifiTask(WifiConfig(strategy=request.param, scenario=SMALL_SCENARIO))


@pytest.fixture(scope="module")
def scenes(task):
    return [task.sample(np.random.default_rng(seed)) for seed in range(3)]


def test_implements_the_task_protocol(task):
    assert isinstance(task, Task)
    assert task.name == f"wifi-s{task.config.strategy}"
    assert task.channels == 1 and task.shape == (64, 64) and task.mission_dimension_px == 64.0


def test_observation_is_the_scaled_density_and_counts_everyone(task, scenes):
    for scene in scenes:
        obs = task.observe(scene)
        assert obs.shape == (1, 64, 64) and obs.dtype == np.float32
        assert obs.sum() * task.config.density_scale == pytest.approx(len(scene.users_m))
        np.testing.assert_array_equal(obs, crowd_raster(scene.users_m, task.config))


def test_expert_obeys_the_strategy_rules_and_beats_no_placement(task, scenes):
    rules = task.rules
    for scene in scenes:
        expert_px = task.expert(scene)
        assert expert_px.dtype == np.float64 and 0 <= len(expert_px) <= MAX_POSITIONS
        expert_m = task.expert_placement_m(scene.users_m, scene.velocities_m_s)
        np.testing.assert_allclose(task.to_metres(expert_px), expert_m, atol=1e-9)
        state = assign_users(scene.users_m, expert_m, rules.radius_m)
        justified = state.exclusive_counts if rules.exclusive else state.counts
        assert np.all(justified > task.config.expert.min_group_size)
        qos = task.qos(scene, expert_px)
        assert 0.0 < qos["qos"] <= 1.0
        assert task.qos(scene, np.zeros((0, 2))) == {
            "qos": 0.0, "qos_s1": 0.0, "qos_s2": 0.0, "mean_throughput_mbps": 0.0}
        if task.config.strategy == 2:  # every covered user gets >= 5 Mbps
            assert np.all(state.counts <= 40)
            assert qos["qos_s2"] == pytest.approx(qos["qos_s1"])


def test_same_seed_same_scene_and_expert(task):
    a, b = (task.sample(np.random.default_rng(7)) for _ in range(2))
    np.testing.assert_array_equal(a.users_m, b.users_m)
    np.testing.assert_array_equal(task.expert(a), task.expert(b))
    c = task.sample(np.random.default_rng(8))
    assert a.users_m.shape != c.users_m.shape or not np.array_equal(a.users_m, c.users_m)


def test_two_groups_of_40_and_one_of_20_get_exactly_two_uavs_in_strategy_1():
    rng = np.random.default_rng(0)
    users = np.concatenate([_blob(rng, (40.0, 40.0), 40), _blob(rng, (150.0, 60.0), 40),
                            _blob(rng, (100.0, 160.0), 20)])
    task = WifiTask(WifiConfig(strategy=1))
    placement = task.expert_placement_m(users)
    assert len(placement) == 2
    centres = np.array([[40.0, 40.0], [150.0, 60.0]])
    assert np.linalg.norm(placement[np.argsort(placement[:, 0])] - centres, axis=1).max() < 10.0
    coverage = evaluate_coverage(users, placement, RadioConfig())
    assert coverage.qos_s1 == pytest.approx(80 / 100)


def test_strategy_2_splits_a_crowd_of_70_between_two_uavs():
    rng = np.random.default_rng(1)
    users = _blob(rng, (100.0, 100.0), 70, spread_m=4.0)
    s2 = WifiTask(WifiConfig(strategy=2)).expert_placement_m(users)
    s1 = WifiTask(WifiConfig(strategy=1)).expert_placement_m(users)
    assert len(s1) == 1 and len(s2) == 2
    counts = assign_users(users, s2, RadioConfig().coverage_radius_m).counts
    assert counts.sum() == 70 and np.all((counts >= 31) & (counts <= 40))


def _clustered_users(seed: int, side_m: float, n_clusters: int, sizes: tuple[int, int]) -> np.ndarray:
    rng = np.random.default_rng(seed)
    centres = rng.uniform(10.0, side_m - 10.0, size=(n_clusters, 2))
    users = [_blob(rng, tuple(c), int(rng.integers(*sizes)), 6.0) for c in centres]
    return np.clip(np.concatenate(users), 0.0, side_m)


def _gap(strategy: int, users: np.ndarray, side_m: float, step_m: float, max_uavs: int) -> float:
    """(exact MILP served - search expert served) / exact served; the expert may beat the grid-bound MILP.

    The search expert is the optimiser the MILP bounds; the strategy-2 group expert trades users for
    margins on purpose (tests/missions/wifi/test_group_expert.py).
    """
    config = WifiConfig(strategy=strategy, expert=WifiExpertConfig(max_uavs=max_uavs, method="search"))
    rules = coverage_rules(config)
    # a generous wall-clock limit: HiGHS proves these optima in seconds on an idle CPU, a busy one is slower
    exact = exact_placement(users, rules, candidate_grid(side_m, side_m, step_m)[0], time_limit_s=400.0)
    assert exact.optimal
    expert = place_uavs(users, rules, side_m, side_m, config.expert)
    assert len(expert) <= max_uavs
    return (exact.n_served - assign_users(users, expert, rules.radius_m).n_served) / exact.n_served


def test_strategy_1_expert_mean_gap_to_the_exact_milp_on_small_scenes():
    # Four clusters of 25-60 users, 3 UAVs, 120 m square; MILP over a 5 m grid (measured: mean 2.3 %,
    # worst 12.9 %, 0 on 5 of 8 scenes; benchmarks/README.md).
    gaps = [_gap(1, _clustered_users(seed, 120.0, 4, (25, 60)), 120.0, 5.0, 3) for seed in range(6)]
    assert np.mean(gaps) <= 0.03
    assert sum(g <= 0.01 for g in gaps) >= 4


def test_strategy_2_expert_matches_the_exact_milp_on_tiny_scenes():
    # The strategy-2 model's LP relaxation is weak: only tiny scenes solve to optimality quickly.
    for seed in (1, 3):
        assert _gap(2, _clustered_users(seed, 60.0, 2, (32, 45)), 60.0, 6.0, 2) <= 0.0


def test_registry_builds_both_strategies_from_the_shipped_configs():
    for name in ("wifi-s1", "wifi-s2"):
        task = make_task(name, REPO / "configs" / "tasks" / f"{name}.toml")
        assert isinstance(task, WifiTask) and task.name == name
        rebuilt = task_factory(task)()
        assert rebuilt.config == task.config


@pytest.mark.parametrize(
    ("values", "match"),
    [
        ({"strategy": 3}, r"WifiConfig.strategy = 3 is out of range"),
        ({"warmup_min_s": 10.0, "warmup_max_s": 5.0}, r"warmup_min_s = 10.0 must be <= warmup_max_s"),
        ({"scenario": {"width_m": 150.0}}, r"width_m = 150.0 must equal height_m"),
        ({"radio": {"altitude_m": 40.0}}, r"radio.altitude_m = 40.0 leaves no coverage"),
        ({"size_px": 4}, r"WifiConfig.size_px = 4 is out of range"),
    ],
    ids=["strategy", "warmup", "square", "altitude", "size"],
)
def test_config_errors_name_the_field(values, match):
    with pytest.raises(ConfigError, match=match):
        WifiConfig.from_dict(values)


def test_wrong_config_class_and_bad_positions():
    with pytest.raises(TypeError, match="WifiTask needs a WifiConfig"):
        WifiTask(ScenarioConfig())  # type: ignore[arg-type]
    task = WifiTask(WifiConfig(scenario=SMALL_SCENARIO))
    scene = task.sample(np.random.default_rng(0))
    with pytest.raises(ValueError, match="finite"):
        task.qos(scene, np.array([[np.nan, 1.0]]))


@pytest.mark.parametrize("seed", range(8))
def test_assign_users_equals_the_broadcast_association(seed):
    """The compiled association equals the (N, K) broadcast it replaces, ties to the lower index."""
    rng = np.random.default_rng(seed)
    users = np.round(rng.uniform(0.0, 200.0, (int(rng.integers(0, 600)), 2)), seed % 3)
    uavs = np.round(rng.uniform(0.0, 200.0, (int(rng.integers(2, 11)), 2)), seed % 3)
    uavs[1] = uavs[0]  # a tie: the lower index serves
    radius_m = float(rng.choice([30.0, 45.5, 90.0]))
    d2 = squared_distances(users, uavs)
    inside = d2 <= radius_m ** 2
    nearest = np.argmin(d2, axis=1) if len(users) else np.zeros(0, np.int64)
    association = np.where(inside[np.arange(len(users)), nearest], nearest, -1)
    state = assign_users(users, uavs, radius_m)
    assert np.array_equal(state.association, association)
    assert np.array_equal(state.distance_sq_m2, d2.min(axis=1, initial=np.inf))
    assert np.array_equal(state.n_covering, inside.sum(axis=1))
    assert np.array_equal(state.counts, np.bincount(association[association >= 0], minlength=len(uavs)))
    alone = association[inside.sum(axis=1) == 1]
    assert np.array_equal(state.exclusive_counts, np.bincount(alone, minlength=len(uavs)))
    assert not np.any(state.association == 1)  # UAV 1 stands on UAV 0: it never wins a tie
