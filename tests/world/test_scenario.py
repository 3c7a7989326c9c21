"""Scenarios: random generation, our TOML files and the Pedsim XML import."""

import warnings
from pathlib import Path

import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.world.pedsim import PedsimImportWarning, load_pedsim_xml
from uav_swarm.world.scenario import (
    AgentGroup,
    Scenario,
    ScenarioConfig,
    ScenarioError,
    Waypoint,
    random_scenario,
)
from uav_swarm.world.scenario_toml import load_scenario

REPO = Path(__file__).resolve().parents[2]
PEDSIM = REPO / "tests" / "data" / "pedsim"
SCENARIOS = REPO / "configs" / "scenarios"


def _point_segment_distance(points, segments):
    """Brute force: distance from points to densely sampled segment points (independent of the library)."""
    t = np.linspace(0.0, 1.0, 2001)
    samples = segments[:, None, :2] + t[None, :, None] * (segments[:, None, 2:] - segments[:, None, :2])
    return np.linalg.norm(points[:, None, None, :] - samples[None], axis=-1).min(axis=-1)


def _load_pedsim(name):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scenario = load_pedsim_xml(PEDSIM / name)
    return scenario, [w for w in caught if issubclass(w.category, PedsimImportWarning)]


# ---------------------------------------------------------------- random scenarios


def test_random_scenario_is_deterministic():
    config = ScenarioConfig()
    first = random_scenario(np.random.default_rng(7), config)
    assert first == random_scenario(np.random.default_rng(7), config)
    assert first != random_scenario(np.random.default_rng(8), config)


@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"seed{s}")
def test_random_scenario_is_valid(seed):
    config = ScenarioConfig()
    s = random_scenario(np.random.default_rng(seed), config)
    lo, hi = config.margin_m, config.width_m - config.margin_m
    assert s.obstacles.shape == (config.n_obstacles, 4)
    assert ((s.obstacles >= lo - 1e-9) & (s.obstacles <= hi + 1e-9)).all()
    lengths = np.hypot(s.obstacles[:, 2] - s.obstacles[:, 0], s.obstacles[:, 3] - s.obstacles[:, 1])
    assert (
        (lengths >= config.obstacle_length_min_m - 1e-9) & (lengths <= config.obstacle_length_max_m + 1e-9)
    ).all()
    # obstacles keep their gap: no endpoint of one is near another
    ends = s.obstacles.reshape(-1, 2)
    d = _point_segment_distance(ends, s.obstacles)
    d[np.arange(len(ends)), np.arange(len(ends)) // 2] = np.inf
    assert d.min() >= config.obstacle_gap_m - 0.05
    # waypoint circles keep the clearance from obstacles
    centres = np.array([[w.x_m, w.y_m] for w in s.waypoints])
    assert len(s.waypoints) == config.n_waypoints
    assert (
        _point_segment_distance(centres, s.obstacles).min()
        >= config.waypoint_radius_m + config.clearance_m - 0.05
    )
    # no spawn rectangle holds or touches a piece of obstacle
    t = np.linspace(0.0, 1.0, 2001)
    samples = s.obstacles[:, None, :2] + t[None, :, None] * (
        s.obstacles[:, None, 2:] - s.obstacles[:, None, :2]
    )
    samples = samples.reshape(-1, 2)
    assert config.n_groups_min <= len(s.groups) <= config.n_groups_max
    for g in s.groups:
        x0, y0, x1, y1 = g.spawn_rectangle_m
        assert lo - 1e-9 <= x0 and x1 <= hi + 1e-9
        gap_x = np.maximum.reduce([x0 - samples[:, 0], samples[:, 0] - x1, np.zeros(len(samples))])
        gap_y = np.maximum.reduce([y0 - samples[:, 1], samples[:, 1] - y1, np.zeros(len(samples))])
        assert np.hypot(gap_x, gap_y).min() >= config.clearance_m - 0.05
        assert config.group_size_min <= g.size <= config.group_size_max
        assert config.route_length_min <= len(g.route) <= config.route_length_max
        assert len(set(g.route)) == len(g.route)
    assert s.n_pedestrians == sum(g.size for g in s.groups)


def test_random_scenario_default_crowd_is_several_hundred():
    sizes = [random_scenario(np.random.default_rng(seed)).n_pedestrians for seed in range(5)]
    assert all(120 <= n <= 800 for n in sizes)


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"group_size_min": 50, "group_size_max": 10}, "group_size_min"),
        ({"obstacle_length_min_m": 50.0, "obstacle_length_max_m": 10.0}, "obstacle_length_min_m"),
        ({"n_waypoints": 2, "route_length_min": 2, "route_length_max": 3}, "route_length_max"),
        ({"width_m": -5.0}, "width_m"),
        ({"spawn_extent_m": 500.0}, "spawn_extent_m"),
    ],
    ids=["sizes", "lengths", "route", "width", "spawn"],
)
def test_scenario_config_rejects_bad_values(changes, field):
    with pytest.raises(ConfigError, match=field):
        ScenarioConfig(**changes)


def test_random_scenario_that_cannot_fit_raises():
    config = ScenarioConfig(
        width_m=60.0,
        height_m=60.0,
        n_waypoints=3,
        n_obstacles=0,
        waypoint_separation_m=59.0,
        route_length_max=2,
        obstacle_length_max_m=20.0,
        spawn_extent_m=5.0,
    )
    with pytest.raises(ScenarioError, match="waypoints"):
        random_scenario(np.random.default_rng(0), config)


# ---------------------------------------------------------------- TOML files


@pytest.mark.parametrize("name", ["plaza", "station"])
def test_example_scenarios_load(name):
    s = load_scenario(SCENARIOS / f"{name}.toml")
    assert s.obstacles.shape[1] == 4 and len(s.obstacles) >= 5
    assert len(s.groups) >= 4 and s.n_pedestrians >= 200
    names = {w.name for w in s.waypoints}
    assert all(set(g.route) <= names for g in s.groups)


GOOD = """
width_m = 50.0
height_m = 40
obstacles = [[10, 0, 10, 20]]

[[waypoints]]
name = "a"
x_m = 5.0
y_m = 5.0
radius_m = 2.0

[[waypoints]]
name = "b"
x_m = 40.0
y_m = 30.0
radius_m = 2.0

[[groups]]
x_m = 30.0
y_m = 20.0
dx_m = 4.0
dy_m = 4.0
size = 7
route = ["a", "b"]
"""


def _write(tmp_path, text):
    path = tmp_path / "scene.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_toml_round_values(tmp_path):
    s = load_scenario(_write(tmp_path, GOOD))
    assert (s.width_m, s.height_m) == (50.0, 40.0)
    np.testing.assert_array_equal(s.obstacles, [[10.0, 0.0, 10.0, 20.0]])
    assert s.waypoints[1] == Waypoint("b", 40.0, 30.0, 2.0)
    assert s.groups == (AgentGroup(30.0, 20.0, 4.0, 4.0, 7, ("a", "b")),)
    assert s.n_pedestrians == 7 and s.origin_m == (0.0, 0.0)


@pytest.mark.parametrize(
    "old, new, pattern",
    [
        ("size = 7", "sise = 7", r"\['groups\[0\]\.sise'\] \(did you mean 'groups\[0\]\.size'"),
        ("size = 7", "size = 0", r"groups\[0\]\.size"),
        ('name = "b"\n', "", r"waypoints\[1\].*missing.*name"),
        ("radius_m = 2.0\n\n[[groups]]", "radius_m = -1.0\n\n[[groups]]", r"waypoints\[1\]\.radius_m"),
        ('route = ["a", "b"]', 'route = ["a", "c"]', r"groups\[0\]\.route.*'c'"),
        ("x_m = 30.0", "x_m = 49.0", r"groups\[0\] spawn rectangle"),
        ("width_m = 50.0", "width = 50.0", r"unknown key\(s\) \['width'\] \(did you mean 'width_m'"),
        ("obstacles = [[10, 0, 10, 20]]", "obstacles = [[10, 0, 10]]", "obstacles"),
        ("height_m = 40", "height_m = [", "invalid TOML"),
    ],
    ids=[
        "unknown-key",
        "size-range",
        "missing-key",
        "radius-range",
        "unknown-route",
        "spawn-outside",
        "top-level-key",
        "obstacle-shape",
        "malformed",
    ],
)
def test_toml_errors_name_the_field(tmp_path, old, new, pattern):
    assert old in GOOD
    with pytest.raises(ScenarioError, match=pattern):
        load_scenario(_write(tmp_path, GOOD.replace(old, new, 1)))


def test_toml_missing_file(tmp_path):
    with pytest.raises(ScenarioError, match="not found"):
        load_scenario(tmp_path / "nope.toml")


def test_scenario_rejects_duplicate_waypoints_and_bad_obstacles():
    w = Waypoint("a", 1.0, 1.0, 1.0)
    with pytest.raises(ScenarioError, match="unique"):
        Scenario(10.0, 10.0, np.zeros((0, 4)), (w, w), ())
    with pytest.raises(ScenarioError, match="shape"):
        Scenario(10.0, 10.0, np.zeros((2, 3)), (w,), ())
    with pytest.raises(ScenarioError, match="width_m"):
        Scenario(0.0, 10.0, np.zeros((0, 4)), (w,), ())


def test_scenario_obstacles_are_read_only():
    s = Scenario(10.0, 10.0, [[1, 1, 2, 2]], (), ())
    with pytest.raises(ValueError):
        s.obstacles[0, 0] = 5.0


# ---------------------------------------------------------------- Pedsim XML


def test_pedsim_scene1():
    s, caught = _load_pedsim("scene1.xml")
    assert len(caught) == 1 and "robot" in str(caught[0].message)
    assert s.origin_m == (-5.0, -5.0)
    assert (s.width_m, s.height_m) == (160.0, 60.0)
    assert s.obstacles.shape == (18, 4)
    np.testing.assert_array_equal(s.obstacles[0], [5.0, 5.0, 155.0, 5.0])
    assert [w.name for w in s.waypoints] == [
        "left_bottom",
        "left_top",
        "right_bottom",
        "right_top",
        "robot_goal",
        "robot_start",
    ]
    assert s.waypoints[0] == Waypoint("left_bottom", 15.0, 15.0, 5.0)
    loop = ("left_top", "left_bottom", "right_bottom", "right_top")
    assert [g.size for g in s.groups] == [1, 100, 100, 60]
    assert s.groups[0].route == loop and s.groups[1].route == loop
    assert s.groups[2].route == ("right_bottom", "right_top", "left_top", "left_bottom")
    assert s.groups[3].route == (
        "right_top",
        "left_top",
        "left_bottom",
    )  # the commented-out waypoint is not read
    assert s.groups[1] == AgentGroup(100.0, 30.0, 50.0, 10.0, 100, loop)


def test_pedsim_small_airport():
    s, caught = _load_pedsim("small_airport.xml")
    assert len(caught) == 1
    message = str(caught[0].message)
    for kind in ("<queue>", "<addqueue>", "<attraction>", "robot", "NonAirport"):
        assert kind in message
    assert [g.size for g in s.groups] == [20, 10, 10, 20, 20, 20]
    assert [len(g.route) for g in s.groups] == [15] * 6  # NonAirport is undefined, queues are skipped
    assert len(s.waypoints) == 21 and s.obstacles.shape == (62, 4)
    assert s.origin_m == (-170.0, -355.0)
    gate = next(w for w in s.waypoints if w.name == "GateD")
    assert (gate.x_m + s.origin_m[0], gate.y_m + s.origin_m[1]) == (210.0, 0.0)
    assert s.obstacles.min() >= 5.0 and s.obstacles[:, [0, 2]].max() <= s.width_m - 5.0


PEDSIM_TINY = """<?xml version="1.0" encoding="UTF-8"?>
<scenario>
  <obstacle x1="-30" y1="-10" x2="-30" y2="10"/>
  <waypoint id="w" x="-50" y="0" r="3"/>
  <agent x="-10" y="0" n="5" dx="4" dy="2" type="1"><addwaypoint id="w"/></agent>
  <agent x="-12" y="3" n="2" dx="0" dy="0" type="0"/>
</scenario>
"""


def test_pedsim_shift_and_agents_without_waypoints(tmp_path):
    path = tmp_path / "tiny.xml"
    path.write_text(PEDSIM_TINY, encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing unsupported here
        s = load_pedsim_xml(path, margin_m=2.0)
    assert s.origin_m == (-55.0, -12.0)
    assert (s.width_m, s.height_m) == (49.0, 24.0)
    np.testing.assert_array_equal(s.obstacles, [[25.0, 2.0, 25.0, 22.0]])
    assert s.groups[0] == AgentGroup(45.0, 12.0, 4.0, 2.0, 5, ("w",))
    assert s.groups[1].route == () and s.groups[1].size == 2


@pytest.mark.parametrize(
    "text, pattern",
    [
        (PEDSIM_TINY[:-20], "malformed"),
        (PEDSIM_TINY.replace('x1="-30"', 'x1="far"'), r"obstacle #1.*x1"),
        (PEDSIM_TINY.replace(' r="3"', ""), r"waypoint #1.*'r'"),
        (PEDSIM_TINY.replace('n="5"', 'n="2.5"'), r"agent #1.*n="),
        (PEDSIM_TINY.replace("scenario>", "world>"), "expected <scenario>"),
        ("<scenario/>", "nothing|no obstacles"),
    ],
    ids=["truncated", "not-a-number", "missing-attribute", "fractional-n", "root", "empty"],
)
def test_pedsim_bad_files_raise_clear_errors(tmp_path, text, pattern):
    path = tmp_path / "bad.xml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ScenarioError, match=pattern):
        load_pedsim_xml(path)


def test_pedsim_missing_file(tmp_path):
    with pytest.raises(ScenarioError, match="not found"):
        load_pedsim_xml(tmp_path / "none.xml")
