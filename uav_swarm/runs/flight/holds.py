"""The separation guard's holds of a flight's vehicles, by vehicle and reason: how many, how long.

:class:`HoldRecord` counts each vehicle's holds (held for which vehicle, a stale position, found outside
its certified disc) and their wall-clock seconds; :func:`holds_text` says them in one line. A status line
sums those of its period (:mod:`uav_swarm.runs.flight.status`); ``summary.json`` and the end table hold
the totals.

Examples:
    >>> holds = HoldRecord()
    >>> holds.decided({2: ("held", 3), 4: None}, now_s=10.0)
    [2]
    >>> holds.decided({2: ("held", 3), 4: ("stale", None)}, now_s=12.5)
    [4]
    >>> holds.decided({2: None, 4: None}, now_s=13.0)
    []
    >>> holds.to_dict(now_s=13.0)[2]
    [{'reason': 'held', 'for_vehicle': 3, 'holds': 1, 'held_s': 3.0}]
    >>> holds_text(holds.to_dict(now_s=13.0)[4])
    'held once, 0.5 s in all: stale position once 0.5 s'
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["AIRBORNE_M", "HoldRecord", "Reason", "holds_text", "reason_text", "short_text"]

AIRBORNE_M = 1.0
"""A vehicle this high above its home, or higher, is in flight (the closest pair *in flight*)."""

Reason = tuple[str, "int | None"]
"""Why a vehicle is held: ``(state, blocker)``, state ``"held"`` (for the blocker's system id, or None),
``"stale"`` (no fresh position) or ``"outside"`` (found outside its certified disc)."""



def reason_text(reason: Reason) -> str:
    """``"held for vehicle 3"``, ``"stale position"``, ``"outside its disc"``.

    >>> reason_text(("held", 3)), reason_text(("stale", None))
    ('held for vehicle 3', 'stale position')
    """
    state, blocker = reason
    if state == "held":
        return "held" if blocker is None else f"held for vehicle {blocker}"
    return {"stale": "stale position", "outside": "outside its disc"}.get(state, state)


def _times(n: int) -> str:
    return "once" if n == 1 else f"{n} times"


class HoldRecord:
    """Each vehicle's holds by reason: how many began and the seconds held (module docstring).

    A hold begins when a vehicle is held for a reason it was not held for at the previous decision
    (held for vehicle 3, then for vehicle 4: two holds) and ends at the first decision that does not
    hold it for that reason, or that leaves it out (landed, lost).
    """

    def __init__(self) -> None:
        self._open: dict[int, tuple[Reason, float]] = {}
        self._closed: dict[int, dict[Reason, list[float]]] = {}  # [holds, seconds]

    def decided(self, reasons: Mapping[int, Reason | None], now_s: float) -> list[int]:
        """Record one decision (``reasons`` by system id, None: not held) at ``now_s``; the holds begun."""
        begun = []
        for sid in [s for s in self._open if s not in reasons]:
            self._close(sid, now_s)
        for sid, reason in reasons.items():
            current = self._open.get(sid)
            if current is not None and current[0] == reason:
                continue
            if current is not None:
                self._close(sid, now_s)
            if reason is not None:
                self._open[sid] = (reason, now_s)
                self._closed.setdefault(sid, {}).setdefault(reason, [0, 0.0])[0] += 1
                begun.append(sid)
        return begun

    def _close(self, sid: int, now_s: float) -> None:
        reason, since_s = self._open.pop(sid)
        self._closed[sid][reason][1] += max(0.0, now_s - since_s)

    def holding(self, system_id: int) -> tuple[Reason, float] | None:
        """The vehicle's hold now and since when (the clock of :meth:`decided`), or None."""
        return self._open.get(system_id)

    def totals(self, now_s: float) -> dict[tuple[int, Reason], tuple[int, float]]:
        """``(holds, seconds)`` by (system id, reason), the holds still open counted up to ``now_s``."""
        out = {(sid, reason): (int(n), s)
               for sid, by in self._closed.items() for reason, (n, s) in by.items()}
        for sid, (reason, since_s) in self._open.items():
            n, s = out[(sid, reason)]
            out[(sid, reason)] = (n, s + max(0.0, now_s - since_s))
        return out

    def to_dict(self, now_s: float) -> dict[int, list[dict[str, Any]]]:
        """Each vehicle's holds for ``summary.json``, longest first: reason, the blocker, count, seconds."""
        out: dict[int, list[dict[str, Any]]] = {}
        for (sid, (state, blocker)), (n, s) in sorted(self.totals(now_s).items(), key=lambda kv: -kv[1][1]):
            out.setdefault(sid, []).append({"reason": state, "for_vehicle": blocker, "holds": n,
                                            "held_s": round(s, 1)})
        return out


def holds_text(entries: Sequence[Mapping[str, Any]]) -> str:
    """One vehicle's holds (:meth:`HoldRecord.to_dict`) in words; ``"not held"`` without any."""
    if not entries:
        return "not held"
    n = sum(e["holds"] for e in entries)
    total_s = sum(e["held_s"] for e in entries)
    parts = ", ".join(f"{short_text((e['reason'], e['for_vehicle']))} {_times(e['holds'])} "
                      f"{e['held_s']:.1f} s" for e in entries)
    return f"held {_times(n)}, {total_s:.1f} s in all: {parts}"


def short_text(reason: Reason) -> str:
    """``"for vehicle 3"``, ``"stale position"``, ``"outside its disc"``."""
    return reason_text(reason).removeprefix("held ") or "held"
