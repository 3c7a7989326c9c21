import numpy as np
import pytest

from typed_config import ConfigError
from uav_swarm.missions.monitoring.guard_repair import RepairConfig, repair_guards
from uav_swarm.missions.monitoring.polygons import Polygon, locate_points
from uav_swarm.missions.monitoring.task import ArtGalleryTask, FortressTask

TASKS = {"agp": ArtGalleryTask(), "fp": FortressTask()}


def _buildings(task, count, seed):
    rng = np.random.default_rng(seed)
    return [task.sample(rng) for _ in range(count)]


def _proposal_sets(scene, rng):
    """Proposals a network could give: none, far off, the expert's jittered, too many, out of the raster."""
    expert = scene.guards_px
    return [
        np.zeros((0, 2)),
        np.array([[0.0, 0.0]]),
        expert + rng.normal(0.0, 3.0, size=expert.shape),
        expert[:1],
        rng.uniform(-10.0, 74.0, size=(10, 2)),
    ]


@pytest.mark.parametrize("name", ["agp", "fp"])
def test_repaired_guards_see_every_witness_and_stand_where_the_mission_allows(name):
    task = TASKS[name]
    rng = np.random.default_rng(1)
    for scene in _buildings(task, 6, seed=11):
        witnesses = task.witnesses(scene.polygon)
        for proposals in _proposal_sets(scene, rng):
            result = repair_guards(scene.polygon, task.region, witnesses, proposals)
            assert task.qos(scene, result.guards_px)["qos"] == 1.0
            codes = locate_points(result.guards_px, scene.polygon.vertices_px)
            assert np.all(codes >= 0) if name == "agp" else np.all(codes < 0)
            assert np.array_equal(result.guards_px, np.rint(result.guards_px))
            assert len(result.guards_px) >= len(scene.guards_px)  # the expert is optimal


@pytest.mark.parametrize("name", ["agp", "fp"])
def test_the_experts_own_guards_come_back_unchanged_in_number(name):
    task = TASKS[name]
    for scene in _buildings(task, 8, seed=5):
        result = repair_guards(scene.polygon, task.region, task.witnesses(scene.polygon), scene.guards_px)
        assert len(result.guards_px) == len(scene.guards_px)
        assert result.n_added == 0


def test_no_redundant_guard_survives():
    task = TASKS["agp"]
    scene = _buildings(task, 1, seed=3)[0]
    witnesses = task.witnesses(scene.polygon)
    crowded = np.repeat(scene.guards_px, 3, axis=0) + np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]] * len(
        scene.guards_px))
    result = repair_guards(scene.polygon, task.region, witnesses, crowded)
    for drop in range(len(result.guards_px)):
        rest = np.delete(result.guards_px, drop, axis=0)
        assert task.qos(scene, rest)["qos"] == 0.0


def test_witnesses_out_of_the_proposals_reach_are_covered_by_added_guards():
    u_shape = Polygon(np.array([[0, 0], [12, 0], [12, 12], [8, 12], [8, 4], [4, 4], [4, 12], [0, 12]]),
                      size_px=16)
    witnesses = np.argwhere(u_shape.pixel_locations() >= 0)[:, ::-1].astype(float)
    proposal = np.array([[6.0, 2.0]])
    result = repair_guards(u_shape, "interior", witnesses, proposal, RepairConfig(move_radius_px=1))
    assert len(result.guards_px) == 2 and result.n_added >= 1  # one guard cannot see both arms


def test_repair_is_deterministic():
    task = TASKS["fp"]
    scene = _buildings(task, 1, seed=8)[0]
    proposals = np.random.default_rng(0).uniform(0, 63, size=(4, 2))
    witnesses = task.witnesses(scene.polygon)
    first = repair_guards(scene.polygon, task.region, witnesses, proposals)
    second = repair_guards(scene.polygon, task.region, witnesses, proposals)
    assert np.array_equal(first.guards_px, second.guards_px)


@pytest.mark.parametrize("bad", [np.array([[np.nan, 1.0]]), np.zeros((2, 3)), np.zeros(3)])
def test_malformed_proposals_are_refused(bad):
    task = TASKS["agp"]
    scene = _buildings(task, 1, seed=2)[0]
    with pytest.raises(ValueError, match="proposals_px"):
        repair_guards(scene.polygon, task.region, task.witnesses(scene.polygon), bad)


def test_a_region_without_pixel_centres_is_refused():
    whole = Polygon(np.array([[0, 0], [7, 0], [7, 7], [0, 7]]), size_px=8)
    with pytest.raises(ValueError, match="no pixel centre"):
        repair_guards(whole, "exterior", np.array([[0.0, 0.0]]), np.zeros((0, 2)))


def test_config_is_validated():
    with pytest.raises(ConfigError, match="move_stride_px"):
        RepairConfig(move_stride_px=0)
