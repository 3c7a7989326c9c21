"""What a ``fly`` run measured, read back from its ``track.csv``: altitude held, distance to target, end.

Shared by the PX4 peer tests and the opt-in SITL tests, so both judge a flight the same way.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

__all__ = ["live_rows", "altitude_share", "final_distance_m", "settled_distance_m"]


def live_rows(out_dir: Path) -> dict[int, list[dict[str, float]]]:
    """Each vehicle's rows of ``track.csv`` while it was live (status ``live``), by system id, in order."""
    rows: dict[int, list[dict[str, float]]] = {}
    with (Path(out_dir) / "track.csv").open(newline="") as stream:
        for row in csv.DictReader(stream):
            if row["status"] != "live" or not row["z_m"]:
                continue
            values = {k: float(v) if v else math.nan for k, v in row.items() if k not in ("status",)}
            rows.setdefault(int(values["system_id"]), []).append(values)
    return rows


def altitude_share(rows: list[dict[str, float]], alt_m: float, tolerance_m: float = 2.0) -> float:
    """The share of ``rows`` whose height ``z_m`` is within ``tolerance_m`` of ``alt_m`` (0 without rows)."""
    if not rows:
        return 0.0
    return sum(abs(row["z_m"] - alt_m) <= tolerance_m for row in rows) / len(rows)


def final_distance_m(rows: list[dict[str, float]]) -> float:
    """Horizontal distance from the last live position to the target it had then (inf without a target)."""
    for row in reversed(rows):
        if not math.isnan(row["target_x_m"]):
            return math.hypot(row["x_m"] - row["target_x_m"], row["y_m"] - row["target_y_m"])
    return math.inf


def settled_distance_m(rows: list[dict[str, float]], jump_m: float = 5.0, grace_s: float = 10.0) -> float:
    """Horizontal distance to the last target the vehicle had time to reach.

    That is :func:`final_distance_m` at the end, unless the planner moved the target by more than
    ``jump_m`` between two records within the last ``grace_s``: then just before the first such move
    (a target given in the last seconds of a flight is not a settled one).
    """
    if not rows:
        return math.inf
    end_s = rows[-1]["time_s"]
    first_jump = None
    for i in range(len(rows) - 1, 0, -1):
        if rows[i]["time_s"] < end_s - grace_s:
            break
        moved = math.hypot(rows[i]["target_x_m"] - rows[i - 1]["target_x_m"],
                           rows[i]["target_y_m"] - rows[i - 1]["target_y_m"])
        if moved > jump_m:
            first_jump = i
    return final_distance_m(rows[:first_jump] if first_jump is not None else rows)
