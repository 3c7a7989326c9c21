"""A small, fast uav_swarm_v0 world for the wrapper tests, and the raw env they are compared with."""

import numpy as np

from uav_swarm.env.parallel import parallel_env

SMALL_WORLD = {
    "scenario": {"width_m": 80.0, "height_m": 80.0, "n_waypoints": 3, "route_length_max": 3,
                 "waypoint_separation_m": 20.0, "n_groups_min": 2, "n_groups_max": 2,
                 "group_size_min": 10, "group_size_max": 10, "n_obstacles": 2},
    "density_shape": (16, 16),
    "patch_px": 5,
    "radio": {"propagation": "paper"},
}
"""80 m x 80 m, 20 pedestrians: three UAVs cover part of the crowd, so rewards are not all zero (nor all one:
the paper's radio, 30 m; the 802.11 radio, the environment's default, reaches every user of this area)."""


def random_actions(env, n_steps: int, seed: int, spread: float = 1.0) -> np.ndarray:
    """(n_steps, n_agents, 2) float32 actions, uniform in the action box stretched ``spread`` times."""
    space = env.action_space(env.possible_agents[0])
    centre, half = (space.low + space.high) / 2, (space.high - space.low) / 2
    rng = np.random.default_rng(seed)
    unit = rng.uniform(-1.0, 1.0, size=(n_steps, len(env.possible_agents), 2))
    return (centre + spread * half * unit).astype(np.float32)


def raw_trajectory(env_kwargs: dict, actions: np.ndarray, seed: int) -> dict[str, np.ndarray]:
    """Step a raw parallel env through ``actions``, resetting (unseeded) after each episode.

    Returns arrays over steps: ``obs`` (T + 1, n, obs_dim) (index t: what the agents see before
    action t, a reset observation after an episode end), ``final_obs`` (T, n, obs_dim) (what step t
    returned), ``reward`` (T,), ``truncated`` (T,), ``terminated`` (T,), ``qos_s1`` (T,), ``state`` (T,
    state_dim) (after step t, before any reset).
    """
    env = parallel_env(**env_kwargs)
    obs, _ = env.reset(seed=seed)
    out = {key: [] for key in ("obs", "final_obs", "reward", "truncated", "terminated", "qos_s1", "state")}
    out["obs"].append(np.stack(list(obs.values())))
    for step_actions in actions:
        obs, rewards, terms, truncs, infos = env.step(dict(zip(env.agents, step_actions, strict=True)))
        assert len(set(rewards.values())) == 1  # one team reward
        out["final_obs"].append(np.stack(list(obs.values())))
        out["reward"].append(next(iter(rewards.values())))
        out["truncated"].append(all(truncs.values()))
        out["terminated"].append(any(terms.values()))
        out["qos_s1"].append(next(iter(infos.values()))["qos_s1"])
        out["state"].append(env.state())
        if not env.agents:
            obs, _ = env.reset()
        out["obs"].append(np.stack(list(obs.values())))
    return {key: np.asarray(value) for key, value in out.items()}
