"""The Wi-Fi task's expert in flight, on each radio.

:func:`replan_expert` binds the replanning expert of
:mod:`uav_swarm.missions.wifi.replan_expert` to a Wi-Fi task: the fresh solve is the task's expert
(``WifiTask.expert_placement_m``), the warm start is the task's own repair and local search from the last
placement (:func:`warm_placement`), and a placement is worth the users it serves by the task's radio and
strategy (:func:`served_users`, under the 802.11 radio with its channel plan).

Example:
    >>> from uav_swarm.missions.wifi.task import WifiConfig, WifiTask
    >>> task = WifiTask(WifiConfig(strategy=2))
    >>> rng = np.random.default_rng(0)
    >>> users = np.vstack([rng.normal((50.0, 50.0), 4.0, (36, 2)), rng.normal((150.0, 140.0), 4.0, (36, 2))])
    >>> expert = replan_expert(task)
    >>> first = expert.place(users)
    >>> second = expert.place(users + 0.5)
    >>> len(first), bool(np.all(np.abs(second - first) < 5.0))
    (2, True)
"""

from __future__ import annotations

import numpy as np

from uav_swarm.missions.wifi.capacitated import complete_capacitated
from uav_swarm.missions.wifi.expert import adopt_placement
from uav_swarm.missions.wifi.replan_expert import ReplanExpert
from uav_swarm.missions.wifi.task import WifiTask
from uav_swarm.world.comms import evaluate_coverage
from uav_swarm.world.wifi.channels import plan_channels

__all__ = ["replan_expert", "served_users", "warm_placement"]


def served_users(task: WifiTask, users_m: np.ndarray, uavs_m: np.ndarray) -> int:
    """Users the placement serves under the task's strategy and radio (802.11: with its channel plan)."""
    uavs_m = np.asarray(uavs_m, np.float64).reshape(-1, 2)
    if len(users_m) == 0 or len(uavs_m) == 0:
        return 0
    radio = task.config.radio
    channels = plan_channels(uavs_m, radio) if radio.propagation == "802.11" else None
    coverage = evaluate_coverage(users_m, uavs_m, radio, channels=channels)
    share = coverage.qos_s1 if task.config.strategy == 1 else coverage.qos_s2
    return int(round(float(share) * len(users_m)))


def warm_placement(task: WifiTask, users_m: np.ndarray, last_m: np.ndarray, warm_moves: int) -> np.ndarray:
    """The last placement made valid on this crowd and improved locally, by the task's own expert steps.

    Under the 802.11 radio: the 802.11 expert's greedy, polish (at most ``warm_moves`` moves) and prune
    from it. Under the paper's radio: the search expert's repair, centring and greedy fill (under
    admission control the capacitated expert's completion).
    """
    config = task.config
    if config.radio.propagation == "802.11":
        expert = config.expert.ieee80211
        return task.refine_80211(users_m, last_m, config=expert.replace(max_moves=warm_moves))
    if task.rules.admission_control:
        return complete_capacitated(users_m, last_m, task.rules, task.width_m, task.height_m,
                                    config.expert.capacitated)
    return adopt_placement(users_m, last_m, task.rules, task.width_m, task.height_m, config.expert)


def replan_expert(task: WifiTask) -> ReplanExpert:
    """The task's expert for a sequence of crowds, with the settings of ``[task.expert.replan]``.

    Strategy 1 solves afresh at every replan (its expert is a stable function of the crowd: the
    settings apply to strategy 2).
    """
    config = task.config.expert.replan
    if task.config.strategy == 1:
        config = config.replace(warm_start=False)
    return ReplanExpert(
        config,
        fresh=task.expert_placement_m,
        warm=lambda users_m, last_m: warm_placement(task, users_m, last_m, config.warm_moves),
        served=lambda users_m, uavs_m: served_users(task, users_m, uavs_m))
