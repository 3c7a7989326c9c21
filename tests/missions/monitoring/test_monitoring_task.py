from pathlib import Path

import numpy as np
import pytest

from learning.task import MAX_POSITIONS, Task
from typed_config import ConfigError
from uav_swarm.missions.monitoring.polygons import PolygonConfig, PolygonSamplingError, locate_points
from uav_swarm.missions.monitoring.task import (
    ArtGalleryTask,
    FortressConfig,
    FortressTask,
    MonitoringConfig,
    rasterize_polygon,
)
from uav_swarm.missions.registry import make_task, task_factory

REPO = Path(__file__).resolve().parents[3]
SMALL = PolygonConfig(max_vertices=12)


@pytest.fixture(scope="module", params=["agp", "fp"])
def task(request):
    if request.param == "agp":
        return ArtGalleryTask(MonitoringConfig(polygon=SMALL))
    return FortressTask(FortressConfig(polygon=SMALL))


@pytest.fixture(scope="module")
def scenes(task):
    return [task.sample(np.random.default_rng(seed)) for seed in range(4)]


def test_implements_the_task_protocol(task):
    assert isinstance(task, Task)
    assert task.channels == 2 and task.shape == (64, 64) and task.mission_dimension_px == 64.0


def test_expert_is_valid_and_sees_everything(task, scenes):
    for scene in scenes:
        expert = task.expert(scene)
        assert expert.dtype == np.float64 and expert.shape[1] == 2
        assert 1 <= len(expert) <= MAX_POSITIONS
        codes = locate_points(expert, scene.polygon.vertices_px)
        assert np.all(codes >= 0) if task.name == "agp" else np.all(codes == -1)
        assert task.qos(scene, expert) == {"qos": 1.0, "seen_fraction": 1.0}
        # Sub-pixel offsets round back to the expert's pixels.
        assert task.qos(scene, expert + 0.3)["qos"] == 1.0


def test_removing_any_guard_of_the_optimum_leaves_the_building_uncovered(task, scenes):
    for scene in scenes:
        expert = task.expert(scene)
        for k in range(len(expert)):
            result = task.qos(scene, np.delete(expert, k, axis=0))
            assert result["qos"] == 0.0 and 0.0 <= result["seen_fraction"] < 1.0


def test_qos_of_no_or_misplaced_guards(task, scenes):
    scene = scenes[0]
    assert task.qos(scene, np.zeros((0, 2))) == {"qos": 0.0, "seen_fraction": 0.0}
    # Positions off the raster are clipped to it; wrong-side guards see nothing.
    inside = np.argwhere(scene.polygon.pixel_locations() == 1)[0][::-1].astype(float)
    wrong = np.array([[-5.0, -5.0]]) if task.name == "agp" else inside[None, :]
    assert task.qos(scene, wrong)["seen_fraction"] == 0.0
    with pytest.raises(ValueError, match=r"finite \(k, 2\)"):
        task.qos(scene, np.array([[np.nan, 1.0]]))


def test_same_seed_same_scene_and_expert(task):
    a = task.sample(np.random.default_rng(77))
    b = task.sample(np.random.default_rng(77))
    c = task.sample(np.random.default_rng(78))
    np.testing.assert_array_equal(a.polygon.vertices_px, b.polygon.vertices_px)
    np.testing.assert_array_equal(task.expert(a), task.expert(b))
    np.testing.assert_array_equal(task.observe(a), task.observe(b))
    assert not np.array_equal(task.observe(a), task.observe(c))


def test_observation_channels(task, scenes):
    for scene in scenes:
        obs = task.observe(scene)
        assert obs.shape == (2, 64, 64) and obs.dtype == np.float32
        assert set(np.unique(obs)) <= {0.0, 1.0}
        np.testing.assert_array_equal(obs[0], scene.polygon.pixel_locations() >= 0)
        for x, y in scene.polygon.vertices_px.astype(int):
            assert obs[1, y, x] == 1.0
        # The boundary separates each filled pixel from an empty 4-neighbour: one of the two is outlined.
        filled, outline = obs[0].astype(bool), obs[1].astype(bool)
        for axis in (0, 1):
            a, b = (filled[1:], filled[:-1]) if axis == 0 else (filled[:, 1:], filled[:, :-1])
            oa, ob = (outline[1:], outline[:-1]) if axis == 0 else (outline[:, 1:], outline[:, :-1])
            assert np.all((oa | ob)[a != b])
        np.testing.assert_array_equal(rasterize_polygon(scene.polygon), obs)


def test_registry_builds_both_tasks_from_the_shipped_configs():
    for name, cls in (("agp", ArtGalleryTask), ("fp", FortressTask)):
        task = make_task(name, REPO / "configs" / "tasks" / f"{name}.toml")
        assert isinstance(task, cls) and task.name == name
        rebuilt = task_factory(task)()
        assert rebuilt.config == task.config


@pytest.mark.parametrize(
    ("cls", "values", "match"),
    [
        (MonitoringConfig, {"max_guards": 11}, "max_guards = 11"),
        (MonitoringConfig, {"guards": 3}, "unknown key"),
        (MonitoringConfig, {"polygon": {"min_vertices": 2}}, "polygon.min_vertices = 2"),
        (MonitoringConfig, {"boundary_spacing_px": 1.0}, "unknown key"),
        (FortressConfig, {"boundary_spacing_px": 0.0}, "boundary_spacing_px = 0.0"),
    ],
)
def test_config_errors(cls, values, match):
    with pytest.raises(ConfigError, match=match):
        cls.from_dict(values)


def test_wrong_config_class_and_impossible_budget():
    with pytest.raises(TypeError, match="FortressConfig"):
        FortressTask(MonitoringConfig())
    # One exterior point never sees a whole boundary: Fortress needs at least two guards.
    task = FortressTask(FortressConfig(polygon=SMALL, max_guards=1, max_redraws=2))
    with pytest.raises(PolygonSamplingError, match="max_redraws|max_guards = 1"):
        task.sample(np.random.default_rng(0))
