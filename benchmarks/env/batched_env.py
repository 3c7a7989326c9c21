"""Agent-steps/s of BatchedUAVSwarm against separate uav_swarm_v0 envs; the crowd against the one before.

For each crowd size (default 200 pedestrians per copy, 5 groups of 40; 516, the default scenario's mean,
6 groups of 86; 1,000, 10 groups of 100) and 10 UAVs, in one run:

- ``copies`` copies (default 64): one ``BatchedUAVSwarm(copies)`` and ``copies`` separate ``uav_swarm_v0``
  parallel envs stepped in a Python loop, both with the current crowd and with the crowd of another commit
  ("before": the crowd's files, ``uav_swarm/world/crowd.py``, ``crowd_batch.py``, ``walls.py``,
  ``walls_batch.py`` and ``pair_forces.py``, as they were at ``--before`` (those it had), by default the
  commit before ``uav_swarm/world/pair_forces.py`` was added, put over a copy of the current packages in a
  temporary folder); with ``--vmas``, also VMAS's ``navigation``
  scenario with ``num_envs=copies`` and 10 agents on the CPU (the ``bench`` extra);
- one env (``uav_swarm_v0``, one copy) with the current crowd and with the one before.

Each implementation runs in its own worker process; the main process steps them in interleaved rounds
(one at a time), so a load that changes during the run affects them alike. Every step draws fresh uniform
random actions from a seeded generator (velocity actions in [-1, 1]). The load average before and after
is printed. Goals: batched >= 5x the separate envs at every crowd size; the single env no slower than
before (<= 1.05x). ``--profile`` prints where a batched step and a single env's step of the current code
spend their time.

Usage: python benchmarks/env/batched_env.py [--pedestrians 200 516 1000] [--copies 64] [--steps 100]
[--single-steps 500] [--rounds 5] [--before REV] [--vmas] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import platform
import pstats
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
KERNEL = "uav_swarm/world/pair_forces.py"
PACKAGES = ("uav_swarm", "typed_config", "learning", "bridge")
CROWD_FILES = ("uav_swarm/world/crowd.py", "uav_swarm/world/crowd_batch.py", "uav_swarm/world/walls.py",
               "uav_swarm/world/walls_batch.py", KERNEL)  # replaced by their old versions (if they existed)
N_UAVS = 10
GROUPS = {200: 5, 516: 6, 1000: 10}  # pedestrians -> groups of equal size
Clocks = tuple[dict[str, list[float]], dict[str, list[float]]]  # wall, CPU seconds per step and round


def crowd_of(pedestrians: int) -> dict:
    """Scenario settings that give exactly ``pedestrians`` per copy."""
    groups = GROUPS.get(pedestrians, 10)
    if pedestrians % groups:
        raise SystemExit(f"--pedestrians {pedestrians}: give a multiple of {groups}")
    size = pedestrians // groups
    return {"n_groups_min": groups, "n_groups_max": groups, "group_size_min": size, "group_size_max": size}


# ---- inside a worker process: build and step environments on command --------------------------------

def stepper(kind: str, copies: int, pedestrians: int) -> Callable[[], None]:
    """One step of ``copies`` worlds: ``batched``, ``separate`` (a Python loop of envs) or ``vmas``."""
    rng = np.random.default_rng(0)
    if kind == "batched":
        from uav_swarm.env.batched import BatchedUAVSwarm

        batch = BatchedUAVSwarm(copies, n_uavs=N_UAVS, scenario=crowd_of(pedestrians), max_cycles=10**6)
        batch.reset(seed=0)
        assert (batch.crowd.counts() == pedestrians).all()

        def step_batch() -> None:
            batch.step(rng.uniform(-1.0, 1.0, size=(copies, N_UAVS, 2)))

        return step_batch
    if kind == "separate":
        from uav_swarm.env.parallel import parallel_env

        envs = [parallel_env(n_uavs=N_UAVS, scenario=crowd_of(pedestrians), max_cycles=10**6)
                for _ in range(copies)]
        for k, env in enumerate(envs):
            env.reset(seed=k)
        agents = envs[0].possible_agents

        def step() -> None:
            for env, action in zip(envs, rng.uniform(-1.0, 1.0, size=(copies, N_UAVS, 2)), strict=True):
                env.step(dict(zip(agents, action, strict=True)))

        return step
    import torch
    import vmas

    world = vmas.make_env(scenario="navigation", num_envs=copies, device="cpu", n_agents=N_UAVS,
                          continuous_actions=True, seed=0)
    world.reset()
    dims = [space.shape[-1] for space in world.action_space]
    return lambda: world.step([torch.from_numpy(rng.uniform(-1.0, 1.0, size=(copies, d)).astype(np.float32))
                               for d in dims])


def profile(step: Callable[[], None], steps: int) -> dict[str, object]:
    """CPU-time profile of ``steps`` steps.

    The share of the crowd's step (with what it calls), and the functions with the most own time.
    """
    profiler = cProfile.Profile(time.process_time)
    profiler.enable()
    for _ in range(steps):
        step()
    profiler.disable()
    stats = vars(pstats.Stats(profiler, stream=io.StringIO()))["stats"]
    total = sum(row[2] for row in stats.values())
    crowd = sum(row[3] for (file, _, name), row in stats.items()  # CrowdSim.step, under BatchedCrowd's too
                if name == "step" and file.endswith("world/crowd.py"))
    rows = sorted(((f"{Path(file).name}:{line}({name})", row[2] / total)
                   for (file, line, name), row in stats.items()), key=lambda r: -r[1])
    return {"crowd": crowd / total, "top": rows[:12]}


def print_profile(what: str, answer: object) -> None:
    """Print a worker's :func:`profile`."""
    assert isinstance(answer, dict)
    print(f"  profile of {what} now: the crowd's step {100 * answer['crowd']:.0f} % of its CPU time; "
          "own time of the functions:")
    for function, share in answer["top"]:
        print(f"    {100 * share:5.1f} %  {function}")


def serve() -> None:
    """Answer the main process's commands, one JSON object a line on stdin, one answer a line on stdout."""
    steppers: dict[str, Callable[[], None]] = {}
    for line in sys.stdin:
        command = json.loads(line)
        answer: object = None
        if command["do"] == "build":
            step = stepper(command["kind"], command["copies"], command["pedestrians"])
            steppers[command["name"]] = step
            for _ in range(3):
                step()  # warm-up: compiled kernels loaded, buffers allocated
        elif command["do"] == "run":
            step, start, start_cpu = steppers[command["name"]], time.perf_counter(), time.process_time()
            for _ in range(command["steps"]):
                step()
            answer = [time.perf_counter() - start, time.process_time() - start_cpu]
        elif command["do"] == "where":
            import uav_swarm.world.crowd

            answer = uav_swarm.world.crowd.__file__
        elif command["do"] == "profile":
            answer = profile(steppers[command["name"]], command["steps"])
        else:
            steppers.clear()
        print(json.dumps(answer), flush=True)


# ---- in the main process ----------------------------------------------------------------------------

class Worker:
    """A worker process running the packages found under ``path``."""

    def __init__(self, path: Path) -> None:
        env = {**os.environ, "PYTHONPATH": str(path)}
        self.process = subprocess.Popen([sys.executable, __file__, "--serve"], cwd=path, env=env, text=True,
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE)

    def ask(self, **command: object) -> object:
        """Send one command; return the answer."""
        assert self.process.stdin is not None and self.process.stdout is not None
        self.process.stdin.write(json.dumps(command) + "\n")
        self.process.stdin.flush()
        line = self.process.stdout.readline()
        if not line:
            raise SystemExit(f"a worker stopped on {command}")
        return json.loads(line)

    def close(self) -> None:
        """End the worker (its input closes)."""
        assert self.process.stdin is not None
        self.process.stdin.close()
        self.process.wait()


def git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()


def before_tree(rev: str | None, folder: Path) -> str:
    """Copy the current packages into ``folder`` with the crowd files of ``rev``; return the commit used."""
    try:
        if rev is None:
            added = git("log", "--diff-filter=A", "--format=%H", "--", KERNEL).splitlines()
            if not added:
                raise SystemExit(f"--before: {KERNEL} was never committed here: give --before REV")
            rev = added[-1] + "^"
        commit = git("rev-parse", "--verify", f"{rev}^{{commit}}")
        for package in PACKAGES:
            if (ROOT / package).is_dir():
                shutil.copytree(ROOT / package, folder / package, ignore=shutil.ignore_patterns("*.pyc"))
        for name in CROWD_FILES:
            if git("ls-tree", "--name-only", commit, "--", name):
                (folder / name).write_text(git("show", f"{commit}:{name}") + "\n", encoding="utf-8")
    except subprocess.CalledProcessError as error:
        raise SystemExit(f"--before {rev}: {error.stderr.strip()}") from None
    return commit[:10]


def measure(steppers: dict[str, tuple[Worker, str]], steps: int, rounds: int
            ) -> Clocks:
    """Wall and CPU seconds per step of each stepper in each round (interleaved, ``steps // rounds`` a round).

    The CPU time is the worker's own (user + system): on a shared machine, the time it really worked.
    """
    per_round = max(1, steps // rounds)
    wall: dict[str, list[float]] = {name: [] for name in steppers}
    cpu: dict[str, list[float]] = {name: [] for name in steppers}
    for _ in range(rounds):
        for name, (worker, key) in steppers.items():
            answer = worker.ask(do="run", name=key, steps=per_round)
            assert isinstance(answer, list)
            wall[name].append(answer[0] / per_round)
            cpu[name].append(answer[1] / per_round)
    return wall, cpu


def cpu_model() -> str:
    """The CPU model name as lscpu reports it."""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return platform.processor() or "unknown"
    return next((line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("Model name")),
                "unknown")


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def ratio(slow: list[float], fast: list[float]) -> str:
    """Total-time ratio, and the range of the per-round ratios."""
    per_round = [s / f for s, f in zip(slow, fast, strict=True)]
    return f"{sum(slow) / sum(fast):5.2f}x ({min(per_round):.2f}-{max(per_round):.2f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pedestrians", type=int, nargs="+", default=[200, 516, 1000], help="crowd sizes")
    parser.add_argument("--copies", type=int, default=64, help="copies of the batched and separate envs")
    parser.add_argument("--steps", type=int, default=100, help="measured steps of the copies, all rounds")
    parser.add_argument("--single-steps", type=int, default=500, help="measured steps of the single env")
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds")
    parser.add_argument("--before", metavar="REV", help="commit of the crowd to compare with")
    parser.add_argument("--vmas", action="store_true", help="add VMAS's navigation scenario (bench extra)")
    parser.add_argument("--profile", action="store_true", help="profile the current batched env's steps")
    parser.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.serve:
        serve()
        return
    for flag in ("copies", "steps", "single_steps", "rounds"):
        if getattr(args, flag) < 1:
            raise SystemExit(f"--{flag.replace('_', '-')} {getattr(args, flag)}: give an integer >= 1")
    for pedestrians in args.pedestrians:
        crowd_of(pedestrians)
    with tempfile.TemporaryDirectory() as tmp:
        commit = before_tree(args.before, Path(tmp))
        now, before = Worker(ROOT), Worker(Path(tmp))
        try:
            run(args, commit, now, before)
        finally:
            now.close()
            before.close()


def milliseconds(clocks: Clocks, name: str, digits: int) -> str:
    """``CPU / wall`` milliseconds per step, means over the rounds."""
    wall, cpu = clocks
    return f"{1e3 * statistics.fmean(cpu[name]):.{digits}f} / {1e3 * statistics.fmean(wall[name]):.{digits}f}"


def report(label: str, slow: str, fast: str, clocks: Clocks, unit: str = "") -> None:
    """One ratio line: by CPU time first, then by wall time."""
    wall, cpu = clocks
    print(f"  {label:<29}cpu {ratio(cpu[slow], cpu[fast])}   wall {ratio(wall[slow], wall[fast])}{unit}")


def run(args: argparse.Namespace, commit: str, now: Worker, before: Worker) -> None:
    print(f"CPU: {cpu_model()}, {os.cpu_count()} logical CPUs; python {platform.python_version()}, "
          f"numpy {np.__version__}; before = the crowd of {commit}")
    for name, worker in (("now", now), ("before", before)):
        print(f"{name}: {worker.ask(do='where')}")
    print(f"load average before: {load()}")
    print(f"{N_UAVS} UAVs per copy; ms per step, CPU / wall, mean over {args.rounds} interleaved rounds; "
          f"ratios of total time (range over rounds)")
    for pedestrians in args.pedestrians:
        copies = args.copies
        steppers = {"batched": (now, "batched"), "separate": (now, "separate"),
                    "batched before": (before, "batched"), "separate before": (before, "separate")}
        if args.vmas:
            steppers["vmas"] = (now, "vmas")
        for worker, kind in steppers.values():
            worker.ask(do="build", name=kind, kind=kind, copies=copies, pedestrians=pedestrians)
        clocks = measure(steppers, args.steps, args.rounds)
        times = ", ".join(f"{name} {milliseconds(clocks, name, 2)}" for name in steppers)
        print(f"\n{pedestrians} pedestrians, {copies} copies: {times}")
        rate = copies * N_UAVS / statistics.fmean(clocks[1]["batched"])
        report("batched/separate now", "separate", "batched", clocks, f"   ({rate:.0f} agent-steps/CPU-s)")
        report("batched/separate before", "separate before", "batched before", clocks)
        report("batched now/separate before", "separate before", "batched", clocks)
        report("batched now/before", "batched before", "batched", clocks, "   as fast")
        report("separate now/before", "separate before", "separate", clocks, "   as fast")
        if args.vmas:
            report("batched/vmas", "vmas", "batched", clocks)
        if args.profile:
            steps = max(5, args.steps // 5)
            print_profile("the batched step", now.ask(do="profile", name="batched", steps=steps))
        for worker in (now, before):
            worker.ask(do="clear")
        for worker in (now, before):
            worker.ask(do="build", name="single", kind="separate", copies=1, pedestrians=pedestrians)
        clocks = measure({"now": (now, "single"), "before": (before, "single")}, args.single_steps,
                         args.rounds)
        print(f"  single env: now {milliseconds(clocks, 'now', 3)} ms, "
              f"before {milliseconds(clocks, 'before', 3)} ms")
        report("single now/before time", "now", "before", clocks)
        if args.profile:
            steps = args.single_steps
            print_profile("the single env's step", now.ask(do="profile", name="single", steps=steps))
        for worker in (now, before):
            worker.ask(do="clear")
    print(f"\nload average after: {load()}")


if __name__ == "__main__":
    main()
