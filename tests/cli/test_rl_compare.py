"""``uav-swarm rl-compare``: the baseline table on shared held-out episodes, and its bad input."""

import json

from uav_swarm.cli import main


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
    assert "unknown controller" in capsys.readouterr().err
    assert main(["rl-compare", "--episodes", "0", "--out", str(tmp_path)]) == 2
    assert not (tmp_path / "comparison.json").exists()
