"""The environment under admission control: the sequence association, capped cells, the infos say which.

Admission control is the paper's radio's; the environment flies the 802.11 radio unless told.
"""

import numpy as np

from uav_swarm.env import parallel_env
from uav_swarm.env.batched import BatchedUAVSwarm


def fly(env, seed, steps=30):
    env.reset(seed=seed)
    centre = {agent: np.array([100.0, 100.0]) for agent in env.possible_agents}
    out = []
    for _ in range(steps):
        _, rewards, _, _, infos = env.step(centre)
        out.append((rewards["uav_0"], infos["uav_0"]["qos_s2"], env.coverage.model,
                    [infos[a]["users_served"] for a in env.possible_agents]))
    return out


def test_no_uav_serves_more_than_its_limit_and_the_coverage_names_the_association():
    env = parallel_env(n_uavs=3, strategy=2, radio={"propagation": "paper", "station_limit": "auto"})
    for reward, qos_s2, association, served in fly(env, seed=4):
        assert max(served) <= 40
        assert association == "admission control (40 stations per UAV)"
        assert reward <= qos_s2  # the team reward is the QoS less the separation penalty
    paper = parallel_env(n_uavs=3, strategy=2, radio={"propagation": "paper"})
    assert fly(paper, seed=4, steps=1)[0][2] == "paper (no admission control)"


def test_same_seed_same_associations():
    def run():
        env = parallel_env(n_uavs=4, strategy=2, radio={"propagation": "paper", "station_limit": 20})
        env.reset(seed=9)
        hold = {a: np.array([60.0 + 25 * i, 100.0]) for i, a in enumerate(env.possible_agents)}
        associations = []
        for _ in range(10):
            env.step(hold)
            associations.append(env.coverage.association.copy())
        return associations
    assert all(np.array_equal(a, b) for a, b in zip(run(), run(), strict=True))


def test_the_batched_view_matches_single_environments_under_admission_control():
    radio = {"propagation": "paper", "station_limit": 15}
    batched = BatchedUAVSwarm(2, n_uavs=3, strategy=2, radio=radio)
    batched.reset(seed=[5, 6])
    singles = [parallel_env(n_uavs=3, strategy=2, radio=radio) for _ in range(2)]
    for seed, env in zip([5, 6], singles, strict=True):
        env.reset(seed=seed)
    actions = np.array([[[50.0, 50.0], [100.0, 100.0], [150.0, 150.0]]] * 2)
    for _ in range(5):
        _, reward, *_ = batched.step(actions)
        for copy, env in enumerate(singles):
            _, rewards, *_ = env.step(dict(zip(env.possible_agents, actions[copy], strict=True)))
            assert reward[copy] == rewards["uav_0"]
