r"""What each peak technique buys on the exact pixel: matched guards on the expert's pixel, and QoS.

    python benchmarks/learning/exact_pixel.py --task fp --data /work/runs-mon/data/fp-6301 \
        --cache /work/runs-mon/cache/fp-6301

On the held-out scenes of a ``split="test"`` dataset (the seeds of ``--data``), for the shipped network
(``--checkpoint``, default the task's) at its mission operating point, each technique's placements are
scored: corr and precision (the paper's rule, ε = 6.4 px), the share of matched guards whose rounded
position is the expert's exact pixel and within 1 px of it (the 3x3 neighbourhood), and the exact QoS
on the regenerated building (guards rounded to pixel centres). The techniques:

- ``targets``: the training targets themselves (the expert rendered as the two Gaussians) through the
  peak step: what the encoding loses before any network;
- ``network``: the network's map through the peak step as shipped;
- ``region``: peaks only on the pixels the mission allows (``PeakConfig.region``, read from the input's
  filled channel);
- ``dark``: the unbiased decoding of DARK (Zhang et al. 2020): the map smoothed by the target's sharp
  Gaussian, its logarithm's Taylor expansion to second order around the peak pixel, the offset
  ``-H⁻¹ g`` (at most 1 px) replacing the parabola; it may move a guard to the neighbouring pixel;
- ``tta``: the mean map of the 8 symmetries of the raster (``--tta-maps``, computed once and cached).

The maps and the regenerated scenes are cached in ``--cache``; the rows are printed as JSON lines
and as a markdown table, with the machine's load.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from scipy import ndimage

from learning.checkpoint import load_checkpoint
from learning.data import load_arrays
from learning.inference import utility_maps
from learning.metrics import MATCH_FRACTION, match_positions
from learning.peaks import PeakConfig, find_peaks
from learning.targets import render_targets
from uav_swarm.missions.registry import build_task

REGIONS = {"agp": "filled", "fp": "empty"}
"""Where each mission's guards stand, as a peak region: inside the building (AGP), outside it (FP)."""


def dark_offsets(utility: np.ndarray, peaks_px: np.ndarray, sigma_px: float = 1.0) -> np.ndarray:
    """The peaks moved by DARK's second-order step on the smoothed log map (at most 1 px per axis).

    Examples:
        >>> ys, xs = np.mgrid[0:9, 0:9]
        >>> u = np.exp(-((xs - 4.3) ** 2 + (ys - 3.8) ** 2) / 2.0)
        >>> dark_offsets(u, np.array([[4.0, 4.0]])).round(1).tolist()
        [[4.3, 3.8]]
    """
    log_map = np.log(np.maximum(ndimage.gaussian_filter(utility.astype(np.float64), sigma_px,
                                                        mode="nearest"), 1e-6))
    h, w = utility.shape
    out = np.array(peaks_px, dtype=np.float64).reshape(-1, 2)
    for k, (x, y) in enumerate(np.rint(out).astype(int)):
        if not (0 < x < w - 1 and 0 < y < h - 1):
            continue
        patch = log_map[y - 1:y + 2, x - 1:x + 2]
        gradient = np.array([patch[1, 2] - patch[1, 0], patch[2, 1] - patch[0, 1]]) / 2.0
        dxx = patch[1, 2] - 2.0 * patch[1, 1] + patch[1, 0]
        dyy = patch[2, 1] - 2.0 * patch[1, 1] + patch[0, 1]
        dxy = (patch[2, 2] - patch[2, 0] - patch[0, 2] + patch[0, 0]) / 4.0
        hessian = np.array([[dxx, dxy], [dxy, dyy]])
        if dxx >= 0.0 or np.linalg.det(hessian) <= 0.0:  # not a maximum: leave the peak
            continue
        out[k] = [x, y] + np.clip(-np.linalg.solve(hessian, gradient), -1.0, 1.0)
    return out


def score(name: str, predicted: list[np.ndarray], experts: list[np.ndarray], qos: Callable[[int, np.ndarray],
          float], eps_px: float) -> dict[str, float | int | str]:
    """One technique's row (percentages)."""
    corr, precision, qos_each = [], [], []
    exact = near = matched = 0
    for i, (expert, placement) in enumerate(zip(experts, predicted, strict=True)):
        pairs = match_positions(expert, placement, eps_px)
        corr.append(len(pairs) / len(expert))
        precision.append(len(pairs) / len(placement) if len(placement) else 0.0)
        if len(pairs):
            gap = np.abs(np.rint(placement[pairs[:, 1]]) - expert[pairs[:, 0]]).max(axis=1)
            exact += int((gap == 0).sum())
            near += int((gap <= 1).sum())
            matched += len(pairs)
        qos_each.append(qos(i, placement))
    return {"technique": name, "corr": 100 * float(np.mean(corr)),
            "precision": 100 * float(np.mean(precision)),
            "exact_pixel": 100 * exact / max(matched, 1), "within_1px": 100 * near / max(matched, 1),
            "qos": 100 * float(np.mean(qos_each)), "matched": matched,
            "positions": int(sum(len(p) for p in predicted)),
            "expert_positions": int(sum(len(e) for e in experts))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", required=True, choices=("agp", "fp"))
    parser.add_argument("--data", required=True, help="a complete split='test' dataset folder")
    parser.add_argument("--cache", required=True, help="folder for the maps and regenerated scenes")
    parser.add_argument("--checkpoint", help="default: uav_swarm/checkpoints/<task>.pt")
    parser.add_argument("--tta-maps", action="store_true", help="also the symmetry-averaged maps")
    args = parser.parse_args()
    torch.set_num_threads(1)
    root = Path(__file__).resolve().parents[2]
    ckpt = load_checkpoint(args.checkpoint or root / "uav_swarm" / "checkpoints" / f"{args.task}.pt",
                           task_name=args.task)
    task = build_task(args.task, ckpt.task_config)
    manifest, arrays = load_arrays(args.data)
    if manifest["split"] != "test":
        parser.error(f"{args.data} is a {manifest['split']!r} split: held-out scenes are split 'test'")
    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    inputs = arrays["inputs"]
    experts = [arrays["positions"][i][arrays["mask"][i]] for i in range(len(inputs))]
    sources = {"network": False, **({"tta": True} if args.tta_maps else {})}
    maps = {}
    for name, tta in sources.items():
        path = cache / f"{'tta' if tta else 'plain'}.npy"
        if not path.is_file():
            np.save(path, utility_maps(ckpt.model, inputs, "float32", tta))
        maps[name] = np.load(path)
    scenes_path = cache / "scenes.pkl"
    if not scenes_path.is_file():
        scenes = [task.sample(np.random.default_rng(int(s))) for s in arrays["seeds"]]
        scenes_path.write_bytes(pickle.dumps(scenes))
    scenes = pickle.loads(scenes_path.read_bytes())
    mission = ckpt.mission_peak_config or ckpt.peak_config
    region = mission.replace(region=REGIONS[args.task])
    eps_px = MATCH_FRACTION * task.mission_dimension_px

    def qos(i: int, placement: np.ndarray) -> float:
        return float(task.qos(scenes[i], placement)["qos"])

    def placements(utilities: np.ndarray | list[np.ndarray], config: PeakConfig, dark: bool = False
                   ) -> list[np.ndarray]:
        out = [find_peaks(u, config, raster=x) for u, x in zip(utilities, inputs, strict=True)]
        return [dark_offsets(u, p) for u, p in zip(utilities, out, strict=True)] if dark else out

    print(f"{args.task}: {len(inputs)} held-out scenes (seed {manifest['seed']}), mission point {mission}; "
          f"load average {os.getloadavg()}", flush=True)
    targets = [render_targets(e, task.shape, ckpt.target_config) / ckpt.target_config.alpha1 for e in experts]
    rows = []
    for name, utilities, config, dark in (
            ("targets", targets, mission, False), ("targets, region", targets, region, False),
            *((f"{source}", maps[source], mission, False) for source in sources),
            *((f"{source}, region", maps[source], region, False) for source in sources),
            *((f"{source}, dark", maps[source], mission, True) for source in sources),
            *((f"{source}, region, dark", maps[source], region, True) for source in sources)):
        rows.append(score(name, placements(utilities, config, dark), experts, qos, eps_px))
        print(json.dumps(rows[-1]), flush=True)
    print(f"\nload average after {os.getloadavg()}\n")
    print("| technique | corr % | precision % | matched on the exact pixel % | within 1 px % | QoS % |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        print(f"| {row['technique']} | {row['corr']:.1f} | {row['precision']:.1f} | {row['exact_pixel']:.1f} "
              f"| {row['within_1px']:.1f} | {row['qos']:.1f} |")


if __name__ == "__main__":
    main()
