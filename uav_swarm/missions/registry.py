"""The task registry: mission names to :class:`learning.task.Task` objects and their settings.

Names: ``wifi-s1``, ``wifi-s2`` (the Wi-Fi task with strategy 1 or 2), ``agp``
(Art Gallery) and ``fp`` (Fortress). Task classes are imported lazily and
building a task imports no torch (data workers only build tasks). A task class
has a class attribute ``config_class`` (its :class:`typed_config.Config`) and is
constructed as ``cls(config)``.

A task settings file (``configs/tasks/<name>.toml``) may hold the tables
``[task]`` (the task's own config), ``[targets]`` (:class:`learning.targets.TargetConfig`),
``[model]``, ``[train]`` and ``[peaks]`` (learning's configs), ``[refine]`` (the mission's
refinement of learned placements, :func:`build_refiner`) and ``[rule_check]`` (Wi-Fi: the
deployment rule checked on the observation, :func:`build_rule_check`); every table is optional.
Without a ``[targets]`` table a task gets the paper's best (α2, σ2) from its grid search:
S1 (50, 50), S2 (30, 30), AGP (40, 40), FP (40, 20) (pixels of the paper's rasters).

Data generation runs in worker processes that rebuild the task from a picklable
:class:`TaskFactory` (name + resolved config), never from a file that might change.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from learning.task import PlacementCheck, Refiner, Task
from typed_config import Config, ConfigError, read_toml, unknown_keys_text

if TYPE_CHECKING:  # torch-importing modules are loaded only by load_settings
    from learning.model import ModelConfig
    from learning.peaks import PeakConfig
    from learning.targets import TargetConfig
    from learning.train import TrainConfig

__all__ = ["TASKS", "TaskEntry", "TaskSettings", "TaskFactory", "make_task", "build_task", "task_factory",
           "build_refiner", "build_rule_check", "load_settings"]


@dataclass(frozen=True)
class TaskEntry:
    """Where a task's class lives, the config values its name fixes, and its default targets."""

    target: str
    fixed: Mapping[str, Any] = field(default_factory=dict)
    alpha2: float = 40.0
    sigma2: float = 40.0


TASKS: dict[str, TaskEntry] = {
    "wifi-s1": TaskEntry("uav_swarm.missions.wifi.task:WifiTask", {"strategy": 1}, alpha2=50.0, sigma2=50.0),
    "wifi-s2": TaskEntry("uav_swarm.missions.wifi.task:WifiTask", {"strategy": 2}, alpha2=30.0, sigma2=30.0),
    "agp": TaskEntry("uav_swarm.missions.monitoring.task:ArtGalleryTask", alpha2=40.0, sigma2=40.0),
    "fp": TaskEntry("uav_swarm.missions.monitoring.task:FortressTask", alpha2=40.0, sigma2=20.0),
}
_SECTIONS = ("task", "targets", "model", "train", "peaks", "refine", "rule_check")


def _entry(name: str) -> TaskEntry:
    if name not in TASKS:
        raise ConfigError(f"task = {name!r} is not allowed: choose one of {sorted(TASKS)}")
    return TASKS[name]


class _TaskClass(Protocol):
    """A mission's Task class: built from its config class."""

    config_class: type[Config]

    def __call__(self, config: Config) -> Task: ...


def _task_class(name: str) -> _TaskClass:
    module_name, _, class_name = _entry(name).target.partition(":")
    task_class: _TaskClass = getattr(importlib.import_module(module_name), class_name)
    return task_class


def build_task(name: str, task_config: Mapping[str, Any] | None = None) -> Task:
    """The task ``name`` with its config built from ``task_config`` (plus the values the name fixes).

    Raises:
        ConfigError: Unknown name, invalid config, or a value that contradicts the name
            (e.g. ``strategy = 2`` for ``wifi-s1``).
    """
    entry = _entry(name)
    values = dict(task_config or {})
    for key, value in entry.fixed.items():
        if values.get(key, value) != value:
            raise ConfigError(f"[task] {key} = {values[key]!r} contradicts task {name!r} (needs {value!r})")
        values[key] = value
    cls = _task_class(name)
    return cls(cls.config_class.from_dict(values, where="[task]"))


@dataclass(frozen=True)
class TaskFactory:
    """A picklable zero-argument callable that rebuilds one task (for worker processes)."""

    name: str
    task_config: Mapping[str, Any]

    def __call__(self) -> Task:
        """Build the task."""
        return build_task(self.name, self.task_config)


def task_factory(task: Task) -> TaskFactory:
    """A factory that rebuilds ``task`` (same name, same resolved config)."""
    return TaskFactory(task.name, task.config.to_dict())


@dataclass(frozen=True)
class TaskSettings:
    """Everything a settings file configures for one task, resolved with defaults."""

    name: str
    task: dict[str, Any]
    targets: TargetConfig
    model: ModelConfig
    train: TrainConfig
    peaks: PeakConfig
    refine: dict[str, Any] = field(default_factory=dict)
    rule_check: dict[str, Any] = field(default_factory=dict)
    peaks_given: dict[str, Any] = field(default_factory=dict)
    """The ``[peaks]`` values the file gave (validated): at evaluation they apply over a checkpoint's."""


def build_refiner(task: Task, refine_table: Mapping[str, Any] | None = None) -> Refiner:
    """The refinement of ``task``'s learned placements, its config from a ``[refine]`` table.

    Art Gallery and Fortress: :class:`uav_swarm.missions.monitoring.task.GuardRefiner` (repair to full
    coverage); Wi-Fi: :class:`uav_swarm.missions.wifi.task.WifiRefiner` (local search on the crowd).

    Raises:
        ConfigError: An invalid ``[refine]`` value.
        TypeError: ``task`` is not a registered mission (it has no ``refiner_class``).
    """
    refiner_class = getattr(type(task), "refiner_class", None)
    if refiner_class is None:
        raise TypeError(f"{type(task).__name__} has no refinement (not a registered mission)")
    defaults = refiner_class.default_settings(task) if hasattr(refiner_class, "default_settings") else {}
    config = refiner_class.config_class.from_dict({**defaults, **dict(refine_table or {})}, where="[refine]")
    return refiner_class(task, config)


def build_rule_check(task: Task, rule_check_table: Mapping[str, Any] | None = None) -> PlacementCheck:
    """The rule check of ``task``'s learned placements, its config from a ``[rule_check]`` table.

    Wi-Fi only: :class:`uav_swarm.missions.wifi.rule_check.WifiRuleCheck`.

    Raises:
        ConfigError: An invalid ``[rule_check]`` value.
        TypeError: ``task`` has no rule check.
    """
    check_class = getattr(type(task), "rule_check_class", None)
    if check_class is None:
        raise TypeError(f"{type(task).__name__} has no rule check (Wi-Fi tasks only)")
    config = check_class.config_class.from_dict(dict(rule_check_table or {}), where="[rule_check]")
    return check_class(task, config)


def _mission_table(name: str, tables: Mapping[str, Any], table: str, attribute: str, what: str
                   ) -> dict[str, Any]:
    """A table configuring a mission's class (``[refine]``, ``[rule_check]``), validated here, built later.

    Raises:
        ConfigError: An invalid value, or the table given for a task without that class.
    """
    values = dict(tables.get(table, {}))
    mission_class = getattr(_task_class(name), attribute, None)
    if mission_class is not None:
        mission_class.config_class.from_dict(values, where=f"[{table}]")
    elif values:
        raise ConfigError(f"[{table}]: task {name!r} has no {what}")
    return values


def _read_tables(config_path: str | Path | None) -> dict[str, Any]:
    if config_path is None:
        return {}
    path = Path(config_path)
    data = read_toml(path)
    unknown = sorted(set(data) - set(_SECTIONS))
    if unknown:
        raise ConfigError(f"{path}: {unknown_keys_text('', unknown, list(_SECTIONS))}")
    return data


def load_settings(name: str, config_path: str | Path | None = None) -> TaskSettings:
    """The task, target, model, training and peak settings of ``name`` from an optional TOML file.

    Raises:
        ConfigError: Unknown task name, unreadable file, unknown table or key, or an invalid value.
    """
    from learning.model import ModelConfig
    from learning.peaks import PeakConfig
    from learning.targets import TargetConfig
    from learning.train import TrainConfig

    entry = _entry(name)
    tables = _read_tables(config_path)
    where = f"{config_path}: " if config_path is not None else ""
    try:
        targets = TargetConfig.from_dict({"alpha2": entry.alpha2, "sigma2": entry.sigma2,
                                          **tables.get("targets", {})}, where="[targets]")
        model = ModelConfig.from_dict(tables.get("model", {}), where="[model]")
        train = TrainConfig.from_dict(tables.get("train", {}), where="[train]")
        peaks = PeakConfig.from_dict(tables.get("peaks", {}), where="[peaks]")
        refine = _mission_table(name, tables, "refine", "refiner_class", "refinement")
        rule_check = _mission_table(name, tables, "rule_check", "rule_check_class", "rule check")
    except ConfigError as exc:
        raise ConfigError(f"{where}{exc}") from None
    return TaskSettings(name, dict(tables.get("task", {})), targets, model, train, peaks, refine, rule_check,
                        dict(tables.get("peaks", {})))


def make_task(name: str, config_path: str | Path | None = None, overrides: Mapping[str, Any] | None = None
              ) -> Task:
    """Build a registered task, its config from the ``[task]`` table of ``config_path`` and ``overrides``.

    Args:
        name: ``"wifi-s1"``, ``"wifi-s2"``, ``"agp"`` or ``"fp"``.
        config_path: Optional task settings TOML (see the module docstring).
        overrides: ``[task]`` values that replace the file's.

    Raises:
        ConfigError: Unknown name, bad file, or invalid config values (named with the file).
    """
    _entry(name)
    table = {**_read_tables(config_path).get("task", {}), **(overrides or {})}
    try:
        return build_task(name, table)
    except ConfigError as exc:
        if config_path is None:
            raise
        raise ConfigError(f"{config_path}: {exc} (the [task] table of task {name!r})") from None
