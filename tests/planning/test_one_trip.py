"""Building planners from a run's config is one trip: one task, each module entered once."""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path
from types import FrameType
from typing import Any

import pytest

import uav_swarm.missions.wifi.task as task_module
import uav_swarm.planning.planner as planner_module
from uav_swarm.missions.wifi.task import WifiTask
from uav_swarm.planning.planner import make_planner, make_planners
from uav_swarm.runs.simulate_config import SimulateConfig, load_simulate_config

PLANNER = str(Path(planner_module.__file__).resolve())
TASK = str(Path(task_module.__file__).resolve())
ROOT = Path(__file__).resolve().parents[2]


class Trips:
    """Counts the entries into each module (a call into it from a stack that holds none of its frames)."""

    def __init__(self, files: tuple[str, ...]) -> None:
        self.files = files
        self.entries: Counter[str] = Counter()
        self.tasks = 0

    def _file(self, frame: FrameType) -> str:
        return str(Path(frame.f_code.co_filename).resolve()) if frame.f_code.co_filename[0] != "<" else ""

    def __call__(self, frame: FrameType, event: str, arg: Any) -> None:
        if event != "call":
            return
        name = self._file(frame)
        if name == TASK and frame.f_code is WifiTask.__init__.__code__:
            self.tasks += 1
        if name not in self.files:
            return
        caller = frame.f_back
        while caller is not None:
            if self._file(caller) == name:
                return
            caller = caller.f_back
        self.entries[name] += 1

    def __enter__(self) -> Trips:
        sys.setprofile(self)
        return self

    def __exit__(self, *exc: object) -> None:
        sys.setprofile(None)


EAGER = {"engine": "torch-eager"}  # one engine: the choice among several is timed, and not what is counted
CONFIGS = {"802.11, rule check, refined": (None, {"planning": {"rule_check": True, "refine": True, **EAGER}}),
           "strategy 2 refined, paper's radio": (ROOT / "configs/simulate/wifi-s2-refined.toml",
                                                 {"planning": EAGER})}


@pytest.mark.parametrize("name", list(CONFIGS))
def test_a_learned_planner_and_its_expert_cost_one_task_and_one_entry_each(name):
    path, overrides = CONFIGS[name]
    config = load_simulate_config(path, {"planner": "learned", "compare_expert": True, **overrides})

    def build():
        return make_planners(["learned", "expert"], config.n_uavs, config.task,
                             checkpoint=config.checkpoint or None, config=config.planning,
                             uav_config=config.uav)

    build()  # the compiled searches warmed up (compiling them under the counter is slow), then counted:
    with Trips((PLANNER, TASK)) as trips:
        planners = build()
    assert trips.tasks == 1
    assert trips.entries == {PLANNER: 1, TASK: 1}
    assert planners["expert"].task is planners["learned"].task


def test_the_expert_alone_costs_one_task():
    config = SimulateConfig(planner="expert")
    with Trips((PLANNER, TASK)) as trips:
        planner = make_planner("expert", config.n_uavs, config.task, config=config.planning,
                               uav_config=config.uav)
    assert (trips.tasks, trips.entries) == (1, {PLANNER: 1, TASK: 1})
    assert planner.task.config.expert.max_uavs == config.n_uavs


def test_the_shared_task_keeps_the_uavs_separation_and_the_networks_raster():
    config = SimulateConfig(planner="learned", compare_expert=True)
    wider = config.uav.replace(min_separation_m=config.task.min_separation_m + 4.0)
    planners = make_planners(["learned", "expert"], 4, config.task, config=config.planning.replace(**EAGER),
                             uav_config=wider)
    task = planners["learned"].task
    assert task.config.min_separation_m == wider.min_separation_m
    assert task.rules.max_uavs == 4
    assert task.channels == planners["learned"].checkpoint.input_shape[0]


def test_the_counter_sees_a_second_trip():
    with Trips((PLANNER, TASK)) as trips:
        make_planner("expert", 2)
        make_planner("expert", 2)
    assert (trips.tasks, trips.entries) == (2, {PLANNER: 2, TASK: 2})
