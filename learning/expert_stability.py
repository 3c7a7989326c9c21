"""How consistent is an expert with itself: the ceiling of what a network can learn from it.

A network sees only the raster. Where two scenes the raster cannot tell apart (or that are
one grid symmetry apart, which training treats as the same scene, see
:class:`learning.loader.ShardDataset`) get expert placements that differ, no network can
match both: the expert's agreement with itself bounds the correspondence and precision
any learned placement can reach against it. Two probes, scored with the paper's rule
(:mod:`learning.metrics`):

- ``"symmetry"``: the expert's placement of scene ``i`` moved by a grid symmetry against
  its placement of the moved scene (the 7 non-identity symmetries in turn). Needs the
  task's ``transform_scene(scene, flip_x, flip_y, transpose)``.
- ``"jitter"``: the expert's placement against its placement of the same scene with every
  element moved by a normal draw of ``scale`` (metres for the Wi-Fi crowds), far below a
  pixel. Needs the task's ``jitter_scene(scene, rng, scale)``. The QoS of both placements
  is measured on the unmoved scene, which tells how sharply the expert's QoS depends on
  positions the raster does not resolve.

Scenes come from the ``test`` seed namespace of ``seed`` (:func:`learning.data.sample_seed`),
the jitter from ``default_rng((seed, i))``; the same arguments give the same report.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import numpy as np

from learning.data import sample_seed
from learning.metrics import MATCH_FRACTION, aggregate, score_sample
from learning.symmetry import SYMMETRIES, inverse_transform_positions, transform_positions
from learning.task import Task

__all__ = ["Probe", "expert_stability"]

Probe = Literal["symmetry", "jitter"]


def expert_stability(task: Task, n: int, seed: int, probe: Probe = "symmetry", scale: float = 0.05
                     ) -> dict[str, Any]:
    """The expert's agreement with itself on ``n`` scenes (see the module docstring).

    Args:
        task: The mission.
        n: Number of scenes (>= 1).
        seed: Seed of the scenes (``test`` namespace) and of the jitter.
        probe: ``"symmetry"`` or ``"jitter"``.
        scale: Jitter standard deviation (the task's scene units); ``probe = "jitter"`` only.

    Returns:
        ``task``, ``probe``, ``n``, ``seed``, (``scale``), ``corr`` and ``precision`` (means over
        scenes, paper rule), ``same_count`` (share of scenes with as many positions in both),
        ``qos`` (the expert on its scene) and ``qos_other`` (the other placement, moved back,
        on the same scene).

    Raises:
        ValueError: ``n < 1``, an unknown probe, ``scale <= 0`` for jitter, or a task without the
            probe's method.
    """
    if n < 1:
        raise ValueError(f"n = {n}: at least one scene is needed")
    method = {"symmetry": "transform_scene", "jitter": "jitter_scene"}.get(probe)
    if method is None:
        raise ValueError(f"probe = {probe!r}: choose 'symmetry' or 'jitter'")
    probe_scene: Callable[..., Any] | None = getattr(task, method, None)
    if not callable(probe_scene):
        raise ValueError(f"task {task.name!r} has no {method}(): the {probe} probe does not apply to it")
    if probe == "jitter" and not scale > 0:
        raise ValueError(f"scale = {scale}: the jitter needs a scale > 0")
    eps = MATCH_FRACTION * task.mission_dimension_px
    scores, same, qos, qos_other = [], [], [], []
    for i in range(n):
        scene = task.sample(np.random.default_rng(sample_seed(seed, "test", i)))
        expert = task.expert(scene)
        if probe == "symmetry":
            symmetry = SYMMETRIES[1 + i % (len(SYMMETRIES) - 1)]
            moved = probe_scene(scene, *symmetry)
            reference = transform_positions(expert, task.shape, *symmetry)
            other = task.expert(moved)
            other_back = inverse_transform_positions(other, task.shape, *symmetry)
        else:
            moved = probe_scene(scene, np.random.default_rng((seed, i)), scale)
            reference = expert
            other = other_back = task.expert(moved)
        scores.append(score_sample(reference, other, eps))
        same.append(len(expert) == len(other))
        qos.append(task.qos(scene, expert)["qos"])
        qos_other.append(task.qos(scene, other_back)["qos"])
    summary = aggregate(scores)
    report: dict[str, Any] = {"task": task.name, "probe": probe, "n": n, "seed": seed}
    if probe == "jitter":
        report["scale"] = scale
    report.update(corr=summary["corr"], precision=summary["precision"], same_count=float(np.mean(same)),
                  qos=float(np.mean(qos)), qos_other=float(np.mean(qos_other)))
    return report

