r"""The curve of QoS against precision on held-out scenes: where the peak settings can take a network.

``uav-swarm calibrate-mission`` chooses the mission point on the validation split; this script scores
the same grid of peak settings on a held-out dataset (for example the ``test-data`` folder that
``uav-swarm evaluate`` generated) to show the best point reachable there, never to choose one.

    python benchmarks/learning/operating_points.py --task agp --checkpoint uav_swarm/checkpoints/agp.pt \
        --data runs/agp/test-seed11 --out results/agp/operating-points/test-front.json

Prints the front (no other point has both a higher precision and a higher QoS), the checkpoint's two
operating points marked, with the machine and its load average.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

from learning.checkpoint import load_checkpoint
from learning.data import load_arrays
from learning.inference import utility_maps
from learning.mission_calibration import MissionGrid, pareto_front, score_grid
from learning.precision import resolve_precision
from typed_config.files import write_json_atomic
from uav_swarm.missions.registry import build_task


def main() -> None:
    """Score the grid on ``--data`` and print the front."""
    grid = MissionGrid()
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", required=True, help="agp, fp, wifi-s1 or wifi-s2")
    parser.add_argument("--checkpoint", required=True, help="the network")
    parser.add_argument("--data", required=True, help="a held-out dataset of the checkpoint's task")
    parser.add_argument("--out", required=True, help="JSON report to write")
    parser.add_argument("--thresholds", type=float, nargs="+", default=list(grid.thresholds),
                        help="threshold_abs values tried (default: %(default)s)")
    parser.add_argument("--contrasts", type=float, nargs="+", default=list(grid.contrasts),
                        help="min_contrast values tried (default: %(default)s)")
    parser.add_argument("--distances-px", type=int, nargs="+", default=list(grid.distances_px),
                        help="min_distance_px values tried (default: %(default)s)")
    args = parser.parse_args()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs; load average {load}")
    ckpt = load_checkpoint(args.checkpoint, task_name=args.task)
    task = build_task(args.task, ckpt.task_config)
    _, arrays = load_arrays(args.data)
    start = time.perf_counter()
    precision = resolve_precision("auto", next(ckpt.model.parameters()).device)
    maps = utility_maps(ckpt.model, arrays["inputs"], precision)
    points = MissionGrid(thresholds=tuple(args.thresholds), contrasts=tuple(args.contrasts),
                         distances_px=tuple(args.distances_px)).configs(ckpt.peak_config)
    named = {"balanced": ckpt.peak_config, "mission": ckpt.mission_peak_config or ckpt.peak_config}
    marked = dict(zip(named, score_grid(task, maps, arrays, list(named.values())), strict=True))
    rows = score_grid(task, maps, arrays, points, progress=True)
    seconds = time.perf_counter() - start
    front = pareto_front(rows)
    print(f"{args.task}: {len(maps)} held-out scenes, {len(rows)} grid points, {seconds:.0f} s")
    print("| point | threshold_abs | min_contrast | min_distance_px | corr % | precision % | QoS rel. % |")
    print("|---|---|---|---|---|---|---|")
    for name, row in [*marked.items(), *(("front", r) for r in front)]:
        print(f"| {name} | {row['threshold_abs']} | {row['min_contrast']} | {row['min_distance_px']} "
              f"| {100 * row['corr']:.1f} | {100 * row['precision']:.1f} | {100 * row['qos_relative']:.1f} |")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(args.out, {"task": args.task, "checkpoint": args.checkpoint, "n_scenes": len(maps),
                                 "load_average": load, "seconds": seconds, **marked, "front": front,
                                 "rows": rows})


if __name__ == "__main__":
    main()
