"""``uav-swarm rl-compare``: the baseline table on shared held-out episodes, and its bad input."""

import json

import pytest

from uav_swarm.cli import main


@pytest.mark.slow
def test_table_rows_are_measured_and_reproducible(tmp_path, capsys) -> None:
    args = ["rl-compare", "--controllers", "random", "expert", "--episodes", "2", "--duration-s", "2",
            "--n-uavs", "3", "--seed", "7"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    first = json.loads((tmp_path / "a" / "comparison.json").read_text())
    second = json.loads((tmp_path / "b" / "comparison.json").read_text())
    rows = {s["controller"]: s for s in first["scores"]}
    assert list(rows) == ["random", "expert"]
    for row in rows.values():
        assert row["episodes"] == 2 and row["steps"] == 20
        assert 0.0 <= row["mean_qos_s2"] <= row["mean_qos_s1"] <= 1.0
        assert row["decision_ms_per_step"] > 0
    assert rows["random"]["replan_ms"] is None and rows["expert"]["replan_ms"] > 0
    # the same seeds give the same worlds and the same random actions
    for key in ("mean_qos_s1", "mean_qos_s2", "mean_throughput_mbps"):
        assert first["scores"][0][key] == second["scores"][0][key]
        assert first["scores"][1][key] == second["scores"][1][key]
    table = (tmp_path / "a" / "comparison.md").read_text()
    assert table.count("\n") == 4 and "| expert |" in table


def test_bad_input_exits_2_with_a_message(tmp_path, capsys) -> None:
    assert main(["rl-compare", "--controllers", "mappo", "--out", str(tmp_path)]) == 2
    assert "needs a policy file" in capsys.readouterr().err
    assert main(["rl-compare", "--controllers", "nobody", "--out", str(tmp_path)]) == 2
    assert "argument --controllers: invalid choice: 'nobody'" in capsys.readouterr().err
    assert main(["rl-compare", "--episodes", "0", "--out", str(tmp_path)]) == 2
    assert not (tmp_path / "comparison.json").exists()


def test_planned_episodes_fly_in_lockstep_as_they_fly_alone() -> None:
    """The planners' episodes are planned together (one network pass per replan): the same flights."""
    import numpy as np

    from uav_swarm.marl import compare
    from uav_swarm.missions.wifi.task import WifiConfig
    from uav_swarm.planning.planner import make_planner
    from uav_swarm.runs.simulate_config import SimulateConfig

    [score] = compare.compare_controllers(["learned"], episodes=3, duration_s=2.0, n_uavs=3, seed=11,
                                          replan_every=5)
    world = SimulateConfig(n_uavs=3, duration_s=2.0, replan_every=5, task=WifiConfig())  # the paper's radio
    planner = make_planner("learned", 3, world.task, config=world.planning, uav_config=world.uav)
    held = {}

    def decide(step, observations, env):
        if step % 5 == 0:
            targets = planner.plan(env.pedestrian_positions_m, env.uav_positions_m,
                                   env.pedestrian_velocities_m_s).targets_m
            held.update(zip(env.agents, targets, strict=True))
        return dict(held)

    alone = []
    for episode in range(3):
        planner.reset()
        held.clear()
        alone.append(compare._episode(world.env_config(), 11 + episode, decide, world.n_steps)[0])
    alone = np.concatenate(alone)
    assert score.steps == world.n_steps == 20 and score.replan_ms > 0
    assert score.mean_qos_s1 == float(alone[:, 0].mean()) and score.mean_qos_s2 == float(alone[:, 1].mean())


def test_the_controllers_flag_offers_every_controller() -> None:
    from uav_swarm.cli import build_parser
    from uav_swarm.cli.conventions import iter_parsers
    from uav_swarm.marl.compare import CONTROLLERS

    parser = dict(iter_parsers(build_parser()))[("rl-compare",)]
    action = next(a for a in parser._actions if "--controllers" in a.option_strings)
    assert tuple(action.choices) == CONTROLLERS
