"""``uav-swarm env-demo``: fly a scripted swarm for one episode and save a picture of it.

The scripted policy (waypoint mode) places the UAVs greedily on the crowd's density map,
each where its coverage disc adds the most pedestrians not yet covered, assigns the targets
to the UAVs with the least total travel (Hungarian) and replans every ``--replan-every-steps`` steps.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from uav_swarm.cli.conventions import number, run_folder_flag

if TYPE_CHECKING:
    import numpy as np

__all__ = ["register", "run", "greedy_targets_m"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``env-demo`` subcommand."""
    parser = subparsers.add_parser(
        "env-demo", help="run one episode of uav_swarm_v0 with a scripted policy and write a PNG",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add = parser.add_argument
    run_folder_flag(parser, "--out", default="out/env-demo", help="output folder")
    add("--seed", type=number(int, ge=0), default=0, help="episode seed")
    add("--n-uavs", type=number(int, ge=1, le=10), default=6, help="number of UAVs")
    add("--steps", type=number(int, ge=1), default=300, help="episode length in steps of 0.1 s")
    add("--strategy", type=int, default=1, choices=(1, 2), help="reward strategy")
    add("--replan-every-steps", type=number(int, ge=1), default=20, dest="replan_every",
        help="steps between replans")
    parser.set_defaults(func=run)


def greedy_targets_m(density: np.ndarray, width_m: float, height_m: float, n_uavs: int,
                     radius_m: float) -> np.ndarray:
    """Greedy max-coverage on the raster: each target covers the most pedestrians not yet covered.

    Args:
        density: (h, w) pedestrian counts per pixel.
        width_m: Area width in metres.
        height_m: Area height in metres.
        n_uavs: Number of targets.
        radius_m: Coverage radius of a UAV (m).

    Returns:
        (n_uavs, 2) target positions in metres (pixel centres).
    """
    import numpy as np
    from scipy.signal import fftconvolve

    from uav_swarm.world.raster import pixels_to_metres

    h, w = density.shape
    cols, rows = np.meshgrid(np.arange(w), np.arange(h))
    centres_m = pixels_to_metres(np.column_stack([cols.ravel(), rows.ravel()]), width_m, height_m, (h, w))
    px_w, px_h = width_m / w, height_m / h
    ky = np.arange(-(h - 1), h)[:, None] * px_h
    kx = np.arange(-(w - 1), w)[None, :] * px_w
    disc = (kx**2 + ky**2 <= radius_m**2).astype(np.float64)  # (2h-1, 2w-1)
    remaining = density.astype(np.float64).copy()
    chosen = []
    for _ in range(n_uavs):
        gain = fftconvolve(remaining, disc, mode="same")  # pedestrians a UAV at each pixel would add
        best = int(np.argmax(gain))
        chosen.append(centres_m[best])
        near = np.linalg.norm(centres_m - centres_m[best], axis=1) <= radius_m
        remaining.ravel()[near] = 0.0
    return np.array(chosen)


def _assign(positions_m: np.ndarray, targets_m: np.ndarray) -> np.ndarray:
    """Targets reordered so that the total travel distance is minimal (Hungarian)."""
    import numpy as np
    from scipy.optimize import linear_sum_assignment

    cost = np.linalg.norm(positions_m[:, None, :] - targets_m[None, :, :], axis=2)
    _, columns = linear_sum_assignment(cost)
    return targets_m[columns]


def run(args: argparse.Namespace) -> int:
    """Run the episode, print a summary and write ``env_demo.png`` into ``--out``."""
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from uav_swarm.env.parallel import parallel_env

    par_env = parallel_env(n_uavs=args.n_uavs, action_mode="waypoint", strategy=args.strategy,
                           max_cycles=args.steps, render_mode="rgb_array")
    par_env.reset(seed=args.seed)
    qos_s1, qos_s2, throughput = [], [], []
    step = 0
    while par_env.agents:
        if step % args.replan_every == 0:
            targets = greedy_targets_m(par_env.density, par_env.width_m, par_env.height_m,
                                       args.n_uavs, par_env.coverage_radius_m)
            targets = _assign(np.asarray(par_env.uav_positions_m), targets)
            actions = dict(zip(par_env.agents, targets, strict=True))
        _, _, _, _, infos = par_env.step(actions)
        info = infos["uav_0"]
        qos_s1.append(info["qos_s1"])
        qos_s2.append(info["qos_s2"])
        throughput.append(info["mean_throughput_mbps"])
        step += 1
    frame = par_env.render()

    figure, (ax_map, ax_qos) = plt.subplots(1, 2, figsize=(12, 5.5), gridspec_kw={"width_ratios": [1, 1.2]})
    ax_map.imshow(frame, extent=(0, par_env.width_m, 0, par_env.height_m))
    ax_map.set(title=f"step {step}: {args.n_uavs} UAVs, {info['n_pedestrians']} pedestrians",
               xlabel="x East (m)", ylabel="y North (m)")
    times_s = np.arange(1, step + 1) * par_env.dt_s
    ax_qos.plot(times_s, qos_s1, label="QoS S1 (share covered)")
    ax_qos.plot(times_s, qos_s2, label="QoS S2 (covered with >= 5 Mbps)")
    ax_qos.set(xlabel="time (s)", ylabel="QoS", ylim=(0, 1.05), title="QoS over time")
    ax_rate = ax_qos.twinx()
    ax_rate.plot(times_s, throughput, color="grey", linestyle="--", label="mean throughput")
    ax_rate.set_ylabel("mean throughput per user (Mbps)")
    lines = ax_qos.get_lines() + ax_rate.get_lines()
    ax_qos.legend(lines, [line.get_label() for line in lines], loc="upper center",
                  bbox_to_anchor=(0.5, -0.12), ncol=3, fontsize=8, frameon=False)  # below: S2 stays visible
    figure.tight_layout()

    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "env_demo.png"
    from typed_config.files import atomic_path

    with atomic_path(path) as tmp:
        figure.savefig(tmp, format="png", dpi=100)
    plt.close(figure)
    print(f"uav_swarm_v0: {args.n_uavs} UAVs, {info['n_pedestrians']} pedestrians, {step} steps "
          f"({step * par_env.dt_s:.1f} s), seed {args.seed}")
    print(f"final QoS S1 {qos_s1[-1]:.3f}, S2 {qos_s2[-1]:.3f}, mean throughput {throughput[-1]:.2f} Mbps; "
          f"episode mean QoS S1 {np.mean(qos_s1):.3f}, S2 {np.mean(qos_s2):.3f}")
    print(f"wrote {path}")
    return 0
