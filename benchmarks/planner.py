"""Full-replan latency of the learned planner against the expert planner on the same scenes.

A replan is everything ``uav-swarm simulate`` does between two environment steps: the learned
planner rasterises the crowd (64x64), runs the utility network (batch 1), extracts the peaks and
assigns them with the Hungarian method (hysteresis on, the previous plan of the same scene); the
expert planner runs the Wi-Fi expert optimiser and the same assignment. Scenes are ``--n`` random
Wi-Fi scenes (``WifiTask.sample``: several hundred pedestrians after a crowd warm-up), 10 UAVs at
random positions. Each scene is planned ``--repeats`` times by the learned planner and once by the
expert. Goals (issue 12): learned median <= 2 ms and p95 <= 4 ms; expert / learned >= 50x. The
CPU's bfloat16 flags are printed first: ``precision = "auto"`` (the planner's default) is bfloat16
where they are present.

The learned planner uses the shipped checkpoint (``uav_swarm/checkpoints/wifi-s1.pt``) when present,
``--checkpoint`` when given, else an untrained network of the shipped architecture (the
``[model]`` table of ``configs/tasks/wifi-s1.toml``) with permissive peak thresholds so that every
replan extracts and assigns 10 peaks (the output says which).

Usage: python benchmarks/planner.py [--n 30] [--repeats 5] [--threads 1] [--precision float32 bfloat16]
"""

from __future__ import annotations

import argparse
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from learning.checkpoint import CHECKPOINT_FORMAT, checkpoint_label, save_checkpoint
from learning.model import build_model
from learning.peaks import PeakConfig, find_peaks
from learning.precision import BF16_CPU_FLAGS, cpu_flags, resolve_precision
from learning.targets import TargetConfig
from learning.train import TrainConfig
from uav_swarm.missions.registry import load_settings
from uav_swarm.missions.wifi.task import WifiConfig, WifiTask, crowd_raster
from uav_swarm.planning.assignment import assign_targets
from uav_swarm.planning.planner import ExpertPlanner, LearnedPlanner, PlannerConfig, default_checkpoint

GOAL_MS = 2.0
GOAL_P95_MS = 4.0
GOAL_RATIO = 50.0
N_UAVS = 10


def untrained_checkpoint(folder: Path) -> Path:
    """A checkpoint file holding a freshly initialised network of the shipped architecture."""
    settings = load_settings("wifi-s1", Path(__file__).parents[1] / "configs" / "tasks" / "wifi-s1.toml")
    torch.manual_seed(0)
    model_config = settings.model.replace(in_channels=1)
    payload = {
        "format": CHECKPOINT_FORMAT, "model_state": build_model(model_config).state_dict(),
        "model_config": model_config.to_dict(), "target_config": TargetConfig().to_dict(),
        "peak_config": PeakConfig(threshold_abs=-1e9, min_contrast=0.0).to_dict(),
        "train_config": TrainConfig().to_dict(), "task_name": "wifi-s1",
        "task_config": WifiConfig().to_dict(),
        "input_shape": [1, 64, 64], "mission_dimension_px": 64.0, "data": {}, "epoch": 0, "step": 0,
        "history": [],
    }
    path = folder / "untrained-wifi-s1.pt"
    save_checkpoint(path, payload)
    return path


def describe(path: Path) -> str:
    """The architecture stored in a checkpoint, in words."""
    config = torch.load(path, map_location="cpu", weights_only=True)["model_config"]
    coords = ", CoordConv" if config["coord_channels"] else ""
    return f"{config['arch']} network (width {config['width']}, depth {config['depth']}{coords})"


def stats(values_ms: list[float]) -> str:
    a = np.asarray(values_ms)
    return f"median {np.median(a):8.3f} ms   p95 {np.percentile(a, 95):8.3f} ms   max {a.max():8.3f} ms"


def breakdown(planner: LearnedPlanner, crowd: np.ndarray, uavs: np.ndarray) -> dict[str, float]:
    """Milliseconds of each stage of one learned replan."""
    t0 = time.perf_counter()
    raster = crowd_raster(crowd, planner.task.config)
    t1 = time.perf_counter()
    utility = planner.utility_map(raster)
    t2 = time.perf_counter()
    peaks = planner.task.to_metres(find_peaks(utility, planner.peak_config, max_peaks=N_UAVS))
    t3 = time.perf_counter()
    assign_targets(uavs, peaks, None, hysteresis_m=planner.config.hysteresis_m)
    t4 = time.perf_counter()
    return {"raster": t1 - t0, "network": t2 - t1, "peaks": t3 - t2, "hungarian": t4 - t3}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30, help="scenes")
    parser.add_argument("--repeats", type=int, default=5, help="learned replans per scene")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="torch threads (PlannerConfig.torch_threads)")
    parser.add_argument("--precision", nargs="+", default=["float32", "bfloat16"],
                        choices=("float32", "bfloat16"))
    parser.add_argument("--checkpoint", type=Path, help="default: the shipped one, else an untrained network")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        path = args.checkpoint or default_checkpoint("wifi-s1")
        which = f"checkpoint {checkpoint_label(path)}"
        if not path.is_file():
            path = untrained_checkpoint(Path(tmp))
            which = (f"UNTRAINED {describe(path)} (no shipped checkpoint), permissive peaks: 10 peaks "
                     "per replan")
        else:
            which += f" ({describe(path)})"
        learned = {p: LearnedPlanner(N_UAVS, checkpoint=path,
                                     config=PlannerConfig(torch_threads=args.threads, precision=p))
                   for p in args.precision}
        expert = ExpertPlanner(N_UAVS)
        task = WifiTask(WifiConfig())
        rng = np.random.default_rng(args.seed)
        scenes = [task.sample(rng).users_m for _ in range(args.n)]
        starts = [rng.uniform(0.0, 200.0, size=(N_UAVS, 2)) for _ in range(args.n)]

        times: dict[str, list[float]] = {p: [] for p in learned}
        stages: dict[str, dict[str, list[float]]] = {p: {} for p in learned}
        expert_ms: list[float] = []
        for planner in learned.values():  # warm-up (first-call allocations, oneDNN kernels)
            for _ in range(5):
                planner.plan(scenes[0], starts[0])
        for crowd, uavs in zip(scenes, starts, strict=True):
            for precision, planner in learned.items():  # interleaved: the machine load hits all alike
                planner.reset()
                for _ in range(args.repeats):
                    times[precision].append(planner.plan(crowd, uavs).latency_ms)
                for stage, seconds in breakdown(planner, crowd, uavs).items():
                    stages[precision].setdefault(stage, []).append(seconds * 1e3)
            expert.reset()
            expert_ms.append(expert.plan(crowd, uavs).latency_ms)

    peds = [len(s) for s in scenes]
    flags = ", ".join(sorted(BF16_CPU_FLAGS & cpu_flags())) or "none"
    print(f"python {platform.python_version()}, torch {torch.__version__}, {platform.machine()}, "
          f"{torch.get_num_threads()} torch thread(s); bfloat16 CPU flags: {flags} (auto -> "
          f"{resolve_precision('auto', torch.device('cpu'))})")
    print(f"{args.n} scenes (WifiConfig defaults, {min(peds)}-{max(peds)} pedestrians), {N_UAVS} UAVs, "
          f"64x64 raster, batch 1; learned: {which}")
    print(f"expert planner (optimiser + Hungarian)       : {stats(expert_ms)}")
    for precision, values in times.items():
        ratio = np.median(expert_ms) / np.median(values)
        meets = np.median(values) <= GOAL_MS and np.percentile(values, 95) <= GOAL_P95_MS
        print(f"learned {precision:<8} (raster+CNN+peaks+Hungarian): {stats(values)}   "
              f"(goal median <= {GOAL_MS:.0f} ms, p95 <= {GOAL_P95_MS:.0f} ms: "
              f"{'meets' if meets else 'misses'})")
        parts = ", ".join(f"{k} {np.median(v):.3f}" for k, v in stages[precision].items())
        print(f"  stages (median ms): {parts}")
        verdict = "meets" if ratio >= GOAL_RATIO else "misses"
        print(f"  expert / learned {precision} median = {ratio:7.1f}x   "
              f"(goal >= {GOAL_RATIO:.0f}x: {verdict})")


if __name__ == "__main__":
    main()
