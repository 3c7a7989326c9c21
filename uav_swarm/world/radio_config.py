"""The settings of the UAV Wi-Fi models: :class:`RadioConfig` (``[task.radio]``).

``propagation`` chooses the model: ``"paper"`` (:mod:`uav_swarm.world.comms`, this class's default, which the
learning tasks keep) or ``"802.11"`` (:mod:`uav_swarm.world.wifi.coverage`, its settings in ``ieee80211``,
:mod:`uav_swarm.world.wifi.config`; the default of ``simulate``, ``fly`` and ``uav_swarm_v0``,
:data:`RUN_PROPAGATION`).

Examples:
    >>> RadioConfig().association_name
    'paper (no admission control)'
    >>> RadioConfig(propagation="802.11").association_name
    '802.11 (airtime fairness, admission on rate (5 Mbps))'
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from typed_config import Config, ConfigError, param
from uav_swarm.world.wifi.config import Ieee80211Config

__all__ = ["RadioConfig", "RUN_PROPAGATION"]

RUN_PROPAGATION: Literal["paper", "802.11"] = "802.11"
"""The radio ``simulate``, ``fly`` and ``uav_swarm_v0`` fly when not told (``RadioConfig()``: the paper's)."""


@dataclass(frozen=True)
class RadioConfig(Config):
    """Parameters of the UAV Wi-Fi model (defaults: the paper's radio with 0.1 at 30 m)."""

    propagation: Literal["paper", "802.11"] = param(
        "paper", doc="radio model: 'paper' (Gaussian signal, capacity shared equally) or '802.11' "
        "(path loss, SINR, MCS rates, airtime; settings in ieee80211)")

    range_m: float = param(30.0, gt=0.0, le=10_000.0,
                           doc="distance (m) at which the rescaled signal equals signal_at_range")
    signal_at_range: float = param(0.1, gt=0.0, lt=1.0,
                                   doc="coverage threshold on the rescaled signal (0..1)")
    sigma_sq_m2: float | None = param(
        None, gt=0.0, doc="Gaussian variance (m^2); None derives it from range_m and signal_at_range; "
        "450 is the paper's value")
    capacity_mbps: float = param(200.0, gt=0.0, doc="UAV capacity (Mbps) shared equally by its users")
    min_user_rate_mbps: float = param(5.0, ge=0.0, doc="per-user rate (Mbps) that strategy 2 requires")
    altitude_m: float = param(0.0, ge=0.0, le=10_000.0,
                              doc="UAV height above the users (m); > 0 uses the 3D distance")
    station_limit: int | Literal["auto", "off"] | None = param(
        None, ge=1, doc="stations a UAV admits (admission control, as an access point's max_num_sta): "
        "an integer 1..floor(capacity_mbps / min_user_rate_mbps), 'auto' for that floor (40 by default), "
        "or 'off' for the paper's model (every user in range joins its strongest UAV); None (not given) is "
        "the paper's model too, except in simulate and fly with strategy 2, which take 'auto'; with "
        "propagation '802.11' an integer caps the stations, 'off' does not, and 'auto' is refused")
    ieee80211: Ieee80211Config = param(Ieee80211Config(),
                                       doc="the 802.11 model's settings (used with propagation = '802.11')")

    def check(self) -> None:
        """Reject settings of the other propagation model, and limits the paper's capacity cannot serve.

        Paper's model: no minimum rate above the capacity, no station limit above capacity / minimum rate.
        """
        if self.propagation == "802.11":
            paper = [name for name in ("range_m", "signal_at_range", "sigma_sq_m2", "capacity_mbps")
                     if getattr(self, name) != getattr(RadioConfig, name)]
            if paper:
                raise ConfigError(f"RadioConfig.{paper[0]} belongs to propagation = 'paper': set "
                                  "propagation = 'paper' for it, or leave it out with propagation = '802.11' "
                                  "(the 802.11 settings: ieee80211)")
            if self.station_limit == "auto":
                raise ConfigError("RadioConfig.station_limit = 'auto' (capacity / minimum rate) belongs to "
                                  "propagation = 'paper': set propagation = 'paper' for it; under '802.11' "
                                  "admission on rate decides, and an integer caps the stations")
            return
        if self.ieee80211 != Ieee80211Config():
            raise ConfigError("RadioConfig.ieee80211 applies only with propagation = '802.11'; "
                              "set propagation = '802.11' or leave ieee80211 out")
        if self.min_user_rate_mbps > self.capacity_mbps:
            raise ConfigError(
                f"RadioConfig.min_user_rate_mbps = {self.min_user_rate_mbps} is out of range: "
                f"allowed 0 <= min_user_rate_mbps <= capacity_mbps ({self.capacity_mbps})")
        if self.station_limit is None or self.station_limit == "off":
            return
        most = self.rate_bound_stations
        if self.station_limit == "auto":
            if most is None:
                raise ConfigError("RadioConfig.station_limit = 'auto' needs min_user_rate_mbps > 0 "
                                  "(the limit is floor(capacity_mbps / min_user_rate_mbps)); give an integer")
        elif most is not None and self.station_limit > most:
            raise ConfigError(
                f"RadioConfig.station_limit = {self.station_limit} is out of range: allowed "
                f"1 <= station_limit <= {most} (capacity_mbps / min_user_rate_mbps = {self.capacity_mbps} / "
                f"{self.min_user_rate_mbps}: more stations could not all get the minimum rate)")

    def for_strategy(self, strategy: int) -> RadioConfig:
        """The radio a strategy runs: under 802.11 an admission on rate not given is the strategy's.

        Strategy 1 counts the users with a usable rate, so no station is refused on rate; strategy 2 counts
        those with ``min_user_rate_mbps``, so an AP admits a station only while every station keeps it. A
        ``rate_admission`` given is kept, and the paper's radio is returned as it is.

        Examples:
            >>> radio = RadioConfig(propagation="802.11")
            >>> radio.for_strategy(1).ieee80211.rate_admission, radio.for_strategy(2).ieee80211.rate_admission
            (False, True)
        """
        if self.propagation != "802.11" or self.ieee80211.rate_admission is not None:
            return self
        return self.replace(ieee80211=self.ieee80211.replace(rate_admission=strategy == 2))

    @property
    def rate_bound_stations(self) -> int | None:
        """``floor(capacity / min_user_rate)``: the most users that all get the minimum rate (None at 0)."""
        if self.min_user_rate_mbps <= 0.0:
            return None
        return int(math.floor(self.capacity_mbps / self.min_user_rate_mbps + 1e-9))

    @property
    def max_stations(self) -> int | None:
        """The station limit in force per UAV, ``None`` for the paper's model (no admission control).

        With propagation ``"802.11"``: the integer ``station_limit`` only (admission on rate is separate).
        """
        if self.propagation == "802.11":
            return self.station_limit if isinstance(self.station_limit, int) else None
        if self.station_limit == "auto":
            return self.rate_bound_stations
        if self.station_limit == "off":
            return None
        return self.station_limit

    @property
    def association_name(self) -> str:
        """Which association runs, in words (outputs and tables say it)."""
        if self.propagation == "802.11":
            wifi = self.ieee80211
            rules = [f"{wifi.fairness} fairness"]
            if wifi.admits_on_rate:
                rules.append(f"admission on rate ({self.min_user_rate_mbps:g} Mbps)")
            if self.max_stations is not None:
                rules.append(f"{self.max_stations} stations per UAV")
            return f"802.11 ({', '.join(rules)})"
        limit = self.max_stations
        return "paper (no admission control)" if limit is None else \
            f"admission control ({limit} stations per UAV)"

    @property
    def radio_and_admission(self) -> str:
        """The radio and the admission a placement is made for, in words (a network must match them).

        Examples:
            >>> RadioConfig(propagation="802.11").for_strategy(1).radio_and_admission
            'the 802.11 radio without admission on rate'
            >>> RadioConfig(station_limit="auto").radio_and_admission
            "the paper's radio with admission control (40 stations per UAV)"
        """
        limit = self.max_stations
        if self.propagation == "802.11":
            rule = "with admission on rate" if self.ieee80211.admits_on_rate else "without admission on rate"
            return f"the 802.11 radio {rule}" + ("" if limit is None else f" and {limit} stations per UAV")
        return ("the paper's radio without admission control" if limit is None else
                f"the paper's radio with admission control ({limit} stations per UAV)")

    @property
    def effective_sigma_sq_m2(self) -> float:
        """The Gaussian variance in use (m^2): ``sigma_sq_m2`` or the one giving the threshold at range."""
        if self.sigma_sq_m2 is not None:
            return self.sigma_sq_m2
        return self.range_m**2 / (2.0 * math.log(1.0 / self.signal_at_range))

    @property
    def coverage_radius_m(self) -> float:
        """Horizontal distance (m) within which the signal reaches ``signal_at_range`` (0 if never)."""
        reach_sq = 2.0 * self.effective_sigma_sq_m2 * math.log(1.0 / self.signal_at_range)
        return math.sqrt(max(0.0, reach_sq - self.altitude_m**2))
