"""A vehicle's own horizontal limits, read from its parameters: the speed, acceleration and jerk it flies.

- **ArduPilot** (Copter): ``WPNAV_SPEED`` (cm/s), ``WPNAV_ACCEL`` (cm/s^2, its acceleration and its
  braking in guided and auto flight) and the position controller's ``PSC_JERK_XY`` (m/s^3);
- **PX4**: ``MPC_XY_VEL_MAX`` (m/s), ``MPC_ACC_HOR`` (m/s^2) and ``MPC_JERK_AUTO`` (m/s^3).

A guard plans each vehicle with the smaller of these and its own settings; a vehicle whose limits
cannot be read is refused by the caller unless the user states them.

Examples:
    >>> from bridge.autopilots import ARDUPILOT
    >>> LIMIT_PARAMS[ARDUPILOT.name]
    (('WPNAV_SPEED', 0.01), ('WPNAV_ACCEL', 0.01), ('PSC_JERK_XY', 1.0))
"""

from __future__ import annotations

from dataclasses import dataclass

from bridge.autopilots import ARDUPILOT, PX4, Conventions
from bridge.config import ProtocolConfig
from bridge.flight.params import ParamError, read_param
from bridge.link.mavlink import MavlinkLink

__all__ = ["HorizontalLimits", "LIMIT_PARAMS", "read_horizontal_limits"]

LIMIT_PARAMS: dict[str, tuple[tuple[str, float], ...]] = {
    ARDUPILOT.name: (("WPNAV_SPEED", 0.01), ("WPNAV_ACCEL", 0.01), ("PSC_JERK_XY", 1.0)),
    PX4.name: (("MPC_XY_VEL_MAX", 1.0), ("MPC_ACC_HOR", 1.0), ("MPC_JERK_AUTO", 1.0)),
}
"""Per autopilot: (speed, acceleration, jerk) parameter names and the factor to SI units."""


@dataclass(frozen=True)
class HorizontalLimits:
    """What a vehicle reports it flies with (SI units) and the parameters it was read from."""

    speed_m_s: float
    accel_m_s2: float
    jerk_m_s3: float
    source: str

    @property
    def per_axis(self) -> bool:
        """Whether its autopilot limits the acceleration on each horizontal axis (PX4's ``MPC_ACC_HOR``)."""
        return "MPC_ACC_HOR" in self.source

    def to_dict(self) -> dict[str, float | str]:
        """For ``summary.json``."""
        return {"speed_m_s": self.speed_m_s, "accel_m_s2": self.accel_m_s2, "jerk_m_s3": self.jerk_m_s3,
                "source": self.source}


def read_horizontal_limits(link: MavlinkLink, system_id: int, conventions: Conventions,
                           protocol: ProtocolConfig | None = None) -> HorizontalLimits:
    """Read the vehicle's horizontal speed, acceleration and jerk (module docstring).

    Raises:
        ParamError: The autopilot has no known limit parameters, a parameter did not answer, or a
            value is not a positive number (naming the vehicle and the parameter).
    """
    names = LIMIT_PARAMS.get(conventions.name)
    if names is None:
        raise ParamError(system_id, "horizontal limits", f"no known limit parameters for {conventions.name}")
    values = []
    for name, factor in names:
        value = read_param(link, system_id, name, bytewise=conventions.param_bytewise,
                           protocol=protocol).value
        if not value > 0:
            raise ParamError(system_id, name, f"reads {value:g}; a positive limit is needed")
        values.append(value * factor)
    return HorizontalLimits(values[0], values[1], values[2], ", ".join(name for name, _ in names))
