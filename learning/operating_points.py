"""Which peak settings run: a checkpoint's operating points, and the user's settings over them.

A checkpoint carries up to two operating points of peak extraction (:class:`learning.peaks.PeakConfig`),
both chosen on its validation split:

- ``balanced``: the settings training calibrated for correspondence + precision
  (:mod:`learning.calibrate`; the checkpoint's ``peak_config``);
- ``mission``: the settings that maximise the mission's QoS with correspondence and precision held
  at floors (:mod:`learning.mission_calibration`; the checkpoint's ``peak_config_mission``, absent
  on a checkpoint never calibrated for its mission).

:func:`choose_peaks` resolves what runs: the operating point asked for (default: ``mission`` where
the checkpoint has it, else ``balanced``), then every value the user gave (a ``[peaks]`` table, a
planner's ``[planning.peaks]``) over it. Nothing the user gave is dropped: a value is applied or
:func:`choose_peaks` raises :class:`typed_config.ConfigError` naming it. The result,
:class:`PeakChoice`, says which settings ran and where they came from, for every output to record.

Examples:
    >>> base = PeakConfig(threshold_abs=0.15)
    >>> choice = choose_peaks(base, None, {"threshold_abs": 0.9}, source="config file agp.toml")
    >>> choice.config.threshold_abs, choice.source
    (0.9, 'config file agp.toml ([peaks] threshold_abs) over the checkpoint (balanced point)')
    >>> choose_peaks(base, None, fixed={"threshold_abs": (0.2, "the rule check")}).source
    'checkpoint (balanced point); threshold_abs from the rule check'
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from learning.peaks import PeakConfig
from typed_config import Config, ConfigError, param

__all__ = ["OPERATING_POINTS", "PeakOverrides", "PeakChoice", "choose_peaks", "point_promises"]

OPERATING_POINTS = ("mission", "balanced")
"""The operating points a checkpoint may carry (see the module docstring)."""


@dataclass(frozen=True)
class PeakOverrides(Config):
    """Peak settings a user gives over a checkpoint's; an absent (None) value keeps the checkpoint's.

    Ranges are :class:`learning.peaks.PeakConfig`'s, checked when the values are applied.
    """

    threshold_abs: float | None = param(None, doc="a peak's value must be at least this")
    threshold_rel: float | None = param(None, doc="... and this fraction of the map's maximum")
    min_contrast: float | None = param(None, doc="a peak must exceed its window's minimum by this much")
    min_distance_px: int | None = param(None, doc="window half-size, minimum peak distance, px")
    max_peaks: int | None = param(None, doc="at most this many peaks")
    subpixel: bool | None = param(None, doc="refine single-pixel peaks with a parabola fit")

    def given(self) -> dict[str, Any]:
        """The values given (not None), by field name."""
        return {key: value for key, value in self.to_dict().items() if value is not None}


@dataclass(frozen=True)
class PeakChoice:
    """The peak settings that run and where they came from.

    Attributes:
        config: The settings.
        operating_point: The checkpoint's point they start from, ``"mission"`` or ``"balanced"``.
        source: Where they come from, in words (``"checkpoint (mission point)"``, or the file or
            flags of the user's values over it).
        overridden: The fields the user's values set.
        fixed: The fields another setting set (the rule check's threshold).
    """

    config: PeakConfig
    operating_point: str
    source: str
    overridden: tuple[str, ...] = ()
    fixed: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """For ``summary.json`` and the planners' summaries."""
        return {"settings": self.config.to_dict(), "operating_point": self.operating_point,
                "source": self.source, "overridden": list(self.overridden)}


def choose_peaks(
    balanced: PeakConfig,
    mission: PeakConfig | None,
    overrides: Mapping[str, Any] | PeakOverrides | None = None,
    *,
    operating_point: str | None = None,
    source: str = "config",
    table: str = "[peaks]",
    fixed: Mapping[str, tuple[Any, str]] | None = None,
) -> PeakChoice:
    """The peak settings that run (see the module docstring).

    Args:
        balanced: The checkpoint's balanced point (its ``peak_config``).
        mission: The checkpoint's mission point, None where it has none.
        overrides: The user's values (a ``[peaks]`` table or :class:`PeakOverrides`); empty: none.
        operating_point: ``"mission"``, ``"balanced"`` or None (mission where the checkpoint has it).
        source: Where ``overrides`` come from, in words (``"config file agp.toml"``).
        table: The name of the user's table in messages (``"[peaks]"``, ``"[planning.peaks]"``).
        fixed: Fields another setting sets, as ``field: (value, that setting's name)`` (the rule
            check's threshold): applied last, and a user's value for one of them is refused.

    Raises:
        ConfigError: An unknown operating point, ``"mission"`` asked of a checkpoint without one, an
            unknown or out-of-range value, or a value for a locked field.
    """
    if operating_point not in (None, *OPERATING_POINTS):
        raise ConfigError(f"operating point {operating_point!r} is not allowed: choose one of "
                          f"{list(OPERATING_POINTS)}")
    if operating_point == "mission" and mission is None:
        raise ConfigError("operating point 'mission': this checkpoint carries no mission point (calibrate "
                          "one with `uav-swarm calibrate-mission`), use 'balanced'")
    point = operating_point or ("mission" if mission is not None else "balanced")
    base = mission if point == "mission" and mission is not None else balanced
    if isinstance(overrides, PeakOverrides):
        given = overrides.given()
    else:
        given = PeakOverrides.from_dict(dict(overrides or {}), where=table).given()
    fixed = dict(fixed or {})
    for key, (_, setter) in fixed.items():
        if key in given:
            raise ConfigError(f"{table} {key} = {given[key]!r} cannot apply: {setter} sets {key}; "
                              "set it there instead")
    text = f"checkpoint ({point} point)"
    if given:
        text = f"{source} ({table} {' '.join(sorted(given))}) over the {text}"
    config = PeakConfig.from_dict({**base.to_dict(), **given, **{k: v for k, (v, _) in fixed.items()}},
                                  where=table)
    text += "".join(f"; {key} from {setter}" for key, (_, setter) in fixed.items())
    return PeakChoice(config, point, text, tuple(sorted(given)), tuple(sorted(fixed)))


def point_promises(calibration: Mapping[str, Any] | None, choice: PeakChoice) -> dict[str, Any]:
    """Which of the paper's columns the settings that run promise, and why (none where they promise none).

    A point promises a column when its validation figure less the calibration's margin reaches the
    paper's (:mod:`learning.mission_calibration`); only the checkpoint's own point, run as calibrated,
    promises anything.

    Args:
        calibration: The checkpoint's ``mission_calibration`` record, None where it has none.
        choice: The settings that run.

    Returns:
        ``columns`` (the promised ones, in the paper's order), ``paper`` (its figures, where known),
        ``margin_z`` (where known) and ``basis`` (in words).

    Examples:
        >>> record = {"paper": {"corr": 0.75}, "margin_z": 2.0, "mission": {"promises": ["corr"]}}
        >>> mission = PeakChoice(PeakConfig(), "mission", "checkpoint (mission point)")
        >>> point_promises(record, mission)["columns"]
        ['corr']
        >>> balanced = PeakChoice(PeakConfig(), "balanced", "checkpoint (balanced point)")
        >>> point_promises(None, balanced)["columns"]
        []
    """
    none: dict[str, Any] = {"columns": [], "paper": {}, "margin_z": None}
    if calibration is None:
        return {**none, "basis": "the checkpoint was never calibrated for its mission (uav-swarm "
                "calibrate-mission)"}
    if choice.overridden or choice.fixed:
        return {**none, "paper": dict(calibration.get("paper", {})),
                "basis": "the settings that run differ from the calibrated point's"}
    point = calibration.get(choice.operating_point, {})
    if "promises" not in point:
        return {**none, "paper": dict(calibration.get("paper", {})),
                "basis": f"the {choice.operating_point} point was chosen without a margin (recalibrate with "
                "uav-swarm calibrate-mission)"}
    return {"columns": list(point["promises"]), "paper": dict(calibration["paper"]),
            "margin_z": calibration["margin_z"],
            "basis": f"the {choice.operating_point} point's validation figures less "
                     f"{calibration['margin_z']} standard errors "
                     f"({calibration.get('n_validation', '?')} validation scenes)"}
