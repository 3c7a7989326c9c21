"""Fit the 802.11 model's free parameters on half of the ns-3 scenes and judge it on the other half.

Reads ``scenes.json`` and the cached ns-3 results (``run_ns3.py``), then:

1. **SINR -> MCS.** ns-3's ideal rate manager uses an MCS from the SNR at which its error model reaches a bit
   error rate of 1e-6 (``ns3_thresholds.py`` reads these thresholds out of ns-3); below -82 dBm a PHY detects
   no preamble at all, so a station that weak never associates (12 dB SNR at 20 MHz with a 7 dB noise
   figure). The model's table is ``max(ideal + offset, floor)``: the floor is that 12 dB, the offset
   (-3..3 dB) the one that gives the most stations of the fitted scenes ns-3's MCS (the MCS that carried
   most of their data; -1 when ns-3 sent nothing).
2. **MAC efficiency, access intensity, hidden-AP weighting, collision time ratio** by a grid search: the
   loss is the sum over the fitted scenes of the squared normalised errors of every AP
   (``|model - ns3| / max(0.15 ns3, 5 Mbps)``) and of every scene total (``|model - ns3| / max(0.10 ns3,
   5 Mbps)``): the acceptance bounds, so 1 is the edge of passing; each capped at 2 (twice its bound), so
   that what the model cannot represent does not pull the parameters away from everything it can.
3. **Judge** on the held-out scenes: per AP within 15 % (5 Mbps under 33 Mbps), scene totals within 10 %,
   the median relative error of stations whose ns-3 seeds agree (coefficient of variation <= 10 %) <= 25 %,
   co-channel sharing (the pairs on one channel over the same pairs on two) and channel separation.

Prints a Markdown table (every scene, both splits; "before": the model with ``--before-tables``, by default
the shipped ones) and the fitted values; ``--write-tables FILE`` rewrites the values of the model's tables
file (``uav_swarm/world/data/wifi_80211ax.toml``) in place, comments kept, and ``--out`` writes everything as
JSON.
``--judge-only`` fits nothing: it judges ``--tables`` (default: the shipped ones) on ``--results`` at
``--guard-interval-us`` (the guard interval those ns-3 runs used: ns-3's default is 3.2 us).

Usage: python benchmarks/radio/ns3/calibrate.py [--results DIR] [--write-tables FILE] [--out fit.json]
       [--before-tables FILE] [--judge-only [--tables FILE] [--guard-interval-us 3.2]]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import platform
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
from loss_matrix import NOISE_20MHZ_DBM
from model_eval import ModelScene, Ns3Scene, load_ns3, model_scene

from uav_swarm.world.wifi.tables import SHIPPED_TABLES, load_wifi_tables

HERE = Path(__file__).resolve().parent
PREAMBLE_DETECTION_DBM = -82.0
"""ns-3's ``ThresholdPreambleDetectionModel::MinimumRssi``: below it a PHY detects nothing (the station never
associates); with the 7 dB noise figure it is 12 dB of SNR at 20 MHz (and over the primary 20 MHz of a wider
channel, which receives its share of the power)."""
AP_TOLERANCE = 0.15
AP_FLOOR_MBPS = 5.0
AP_FLOOR_BELOW_MBPS = 33.0
SCENE_TOLERANCE = 0.10
STATION_MEDIAN_BOUND = 0.25
SEEDS_AGREE_CV = 0.10
LOSS_CAP = 2.0
"""An error counts at most as twice its bound in the fit: a scene the model cannot represent (ten co-channel
APs whose collisions ns-3 simulates and the model's ideal CSMA has not) does not drag all others off."""
EFFICIENCIES = np.round(np.arange(0.70, 0.981, 0.005), 3)
INTENSITIES = (2.0, 5.0, 10.0, 20.0, 30.0, 50.0, 75.0, 100.0, 200.0, 500.0)
WEIGHTINGS = (0.0, 0.5, 1.0)
COLLISION_RATIOS = (0.0, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0)


def misclassified(sinr_db: np.ndarray, mcs: np.ndarray, thresholds_db: np.ndarray) -> int:
    """Stations whose MCS under ``thresholds_db`` (the model's rule) differs from ns-3's."""
    return int(np.sum(np.searchsorted(thresholds_db, sinr_db, side="right") - 1 != mcs))


def fit_thresholds(sinr_db: np.ndarray, mcs: np.ndarray, ideal_db: np.ndarray, floor_db: float
                   ) -> tuple[np.ndarray, float]:
    """``max(ideal + offset, floor)``, the offset (0.1 dB steps, -3..3) misclassifying the fewest stations."""
    best = (len(mcs) + 1, 0.0)
    for offset in sorted(np.round(np.arange(-3.0, 3.01, 0.1), 1), key=abs):  # ties: the smallest shift
        wrong = misclassified(sinr_db, mcs, np.maximum(ideal_db + offset, floor_db))
        if wrong < best[0]:
            best = (wrong, float(offset))
    return np.round(np.maximum(ideal_db + best[1], floor_db), 1), best[1]


def write_tables(template: Path, out: Path, min_sinr_db: np.ndarray, efficiency: float, intensity: float,
                 weighting: float, collision_ratio: float) -> None:
    """Copy the tables file with the fitted values in place of the old ones (atomic)."""
    text = template.read_text(encoding="utf-8")
    values = {"min_sinr_db": "[" + ", ".join(f"{v:.1f}" for v in min_sinr_db) + "]",
              "efficiency": f"{efficiency:.3f}", "access_intensity": f"{intensity:.1f}",
              "interference_airtime_weighting": f"{weighting:.2f}",
              "collision_time_ratio": f"{collision_ratio:.2f}"}
    for key, value in values.items():
        text, n = re.subn(rf"^{key} = .*$", f"{key} = {value}", text, count=1, flags=re.MULTILINE)
        if n != 1:
            raise ValueError(f"{template}: no line '{key} = ...' to replace")
    tmp = out.with_suffix(".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, out)


def ap_errors(model: ModelScene, ns3: Ns3Scene) -> np.ndarray:
    """(K,) normalised AP errors: ``|model - ns3| / max(0.15 ns3, 5)`` under 33 Mbps, else over 0.15 ns3."""
    truth = ns3.ap_mbps.mean(axis=0)
    bound = np.where(truth < AP_FLOOR_BELOW_MBPS, np.maximum(AP_TOLERANCE * truth, AP_FLOOR_MBPS),
                     AP_TOLERANCE * truth)
    return np.abs(model.ap_mbps - truth) / bound


def scene_error(model: ModelScene, ns3: Ns3Scene) -> float:
    """Relative error of the scene total (where ns-3 delivers nothing: 0 when the model agrees, else inf)."""
    truth = float(ns3.ap_mbps.sum(axis=1).mean())
    gap = float(model.ap_mbps.sum()) - truth
    if truth <= 0.0:
        return 0.0 if abs(gap) < 0.5 else float("inf")
    return gap / truth


def station_errors(model: ModelScene, ns3: Ns3Scene) -> np.ndarray:
    """Relative errors of the stations whose ns-3 seeds agree (coefficient of variation <= 10 %)."""
    mean = ns3.station_mbps.mean(axis=0)
    spread = ns3.station_mbps.std(axis=0)
    agree = (mean > 0) & (spread <= SEEDS_AGREE_CV * np.maximum(mean, 1e-9))
    return np.abs(model.station_mbps[agree] - mean[agree]) / mean[agree]


def _loss(models: list[ModelScene], results: list[Ns3Scene]) -> float:
    """Sum of squared normalised errors, each capped at ``LOSS_CAP`` (a robust loss, module docstring)."""
    total = 0.0
    for model, ns3 in zip(models, results, strict=True):
        truth = float(ns3.ap_mbps.sum(axis=1).mean())
        scene = (float(model.ap_mbps.sum()) - truth) / max(SCENE_TOLERANCE * truth, AP_FLOOR_MBPS)
        errors = np.append(ap_errors(model, ns3), scene)
        total += float(np.sum(np.minimum(errors**2, LOSS_CAP**2)))
    return total


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=Path, default=HERE / "scenes.json")
    parser.add_argument("--results", type=Path, default=HERE / "results")
    parser.add_argument("--ideal", type=Path, default=HERE / "ns3_ideal_thresholds.json",
                        help="ns-3's ideal-manager thresholds (ns3_thresholds.py)")
    parser.add_argument("--write-tables", type=Path, default=None, help="tables TOML to rewrite with the fit")
    parser.add_argument("--out", type=Path, default=None, help="JSON of the fit and every scene's figures")
    parser.add_argument("--before-tables", type=Path, default=SHIPPED_TABLES,
                        help="the tables of the 'before' column (default: the shipped ones)")
    parser.add_argument("--judge-only", action="store_true", help="fit nothing: judge --tables on --results")
    parser.add_argument("--tables", type=Path, default=SHIPPED_TABLES, help="the tables --judge-only judges")
    parser.add_argument("--guard-interval-us", type=float, default=0.8, choices=(0.8, 1.6, 3.2),
                        help="the guard interval of the ns-3 runs in --results (the model runs with it)")
    args = parser.parse_args()
    scenes = [s for s in json.loads(args.scenes.read_text(encoding="utf-8"))["scenes"]
              if (args.results / f"{s['name']}.json").exists()]
    if not scenes:
        print(f"--results {args.results}: no ns-3 results yet (run run_ns3.py)", file=sys.stderr)
        return 2
    ns3 = {s["name"]: load_ns3(args.results / f"{s['name']}.json", s) for s in scenes}
    wrong_gi = sorted(name for name, result in ns3.items()
                      if result.guard_interval_us != args.guard_interval_us)
    if wrong_gi:
        print(f"--guard-interval-us {args.guard_interval_us}: ns-3 ran {wrong_gi} at another guard interval",
              file=sys.stderr)
        return 2
    if not args.judge_only and args.guard_interval_us != 0.8:
        print("--guard-interval-us: the tables are fitted at 0.8 us; judge other runs with --judge-only",
              file=sys.stderr)
        return 2
    gi = args.guard_interval_us
    before_tables = str(args.before_tables)

    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, python {platform.python_version()}; "
          f"load average {' '.join(Path('/proc/loadavg').read_text().split()[:3])}")
    if args.judge_only:
        print(f"judged: {args.tables} at a {gi} us guard interval on {len(scenes)} scenes of {args.results}")
        rows = [(s, model_scene(s, str(args.tables), guard_interval_us=gi),
                 model_scene(s, before_tables, guard_interval_us=gi)) for s in scenes]
        report = _report(rows, ns3)
        if args.out:
            _write_json(args.out, {"guard_interval_us": gi, "tables": str(args.tables), **report})
        return 0

    fit = [s for s in scenes if s["split"] == "fit"]
    shipped = load_wifi_tables(SHIPPED_TABLES)
    with tempfile.TemporaryDirectory() as tmp:
        # 1. SINR -> MCS from the fitted scenes' stations (SINR: the shipped model's, which the thresholds
        #    do not change for users it associates; below MCS 0 the model still reports the SINR).
        sinr = np.concatenate([model_scene(s).sinr_db for s in fit])
        mcs = np.concatenate([ns3[s["name"]].mcs for s in fit])
        ideal = np.asarray(json.loads(args.ideal.read_text(encoding="utf-8"))["min_snr_db"]["20"])
        floor_db = PREAMBLE_DETECTION_DBM - NOISE_20MHZ_DBM
        thresholds, offset = fit_thresholds(sinr, mcs, ideal, floor_db)
        misfits = (misclassified(sinr, mcs, shipped.min_sinr_db), misclassified(sinr, mcs, thresholds),
                   len(mcs))
        # 2. Efficiency, access intensity, hidden-AP weighting and collision time ratio: grid search on the
        #    fitted scenes.
        best = (np.inf, 0.0, 0.0, 0.0, 0.0)
        for intensity, weighting, ratio in itertools.product(INTENSITIES, WEIGHTINGS, COLLISION_RATIOS):
            path = Path(tmp) / f"tables-{intensity}-{weighting}-{ratio}.toml"
            write_tables(SHIPPED_TABLES, path, thresholds, 1.0, intensity, weighting, ratio)
            unit = [model_scene(s, str(path), 1.0) for s in fit]  # throughput is linear in the efficiency
            for efficiency in EFFICIENCIES:
                scaled = [ModelScene(m.station_mbps * efficiency, m.ap_mbps * efficiency, m.sinr_db, m.mcs,
                                     m.airtime) for m in unit]
                loss = _loss(scaled, [ns3[s["name"]] for s in fit])
                if loss < best[0] - 1e-9:
                    best = (loss, float(efficiency), intensity, weighting, ratio)
        loss, efficiency, intensity, weighting, ratio = best
        final = Path(tmp) / "fitted.toml"
        write_tables(SHIPPED_TABLES, final, thresholds, efficiency, intensity, weighting, ratio)
        rows = [(s, model_scene(s, str(final)), model_scene(s, before_tables)) for s in scenes]

    print(f"fitted on {len(fit)} scenes ({', '.join(s['name'] for s in fit)})")
    print(f"ns-3 ideal thresholds (20 MHz) {ideal.tolist()} dB; offset {offset:+.1f} dB; "
          f"floor {floor_db:.1f} dB (-82 dBm preamble detection over the 20 MHz noise)")
    print(f"min_sinr_db = {thresholds.tolist()}; stations of the fitted scenes whose MCS differs from "
          f"ns-3's: shipped table {misfits[0]}, fitted {misfits[1]} of {misfits[2]}")
    print(f"efficiency = {efficiency}, access_intensity = {intensity}, interference_airtime_weighting = "
          f"{weighting}, collision_time_ratio = {ratio}; loss {loss:.2f} over {len(fit)} scenes")
    report = _report(rows, ns3)
    if args.write_tables:
        write_tables(args.write_tables, args.write_tables, thresholds, efficiency, intensity, weighting,
                     ratio)
        print(f"wrote the fit into {args.write_tables}")
    if args.out:
        _write_json(args.out, {
            "min_sinr_db": thresholds.tolist(), "ns3_ideal_db": ideal.tolist(), "offset_db": offset,
            "floor_db": floor_db, "mcs_misclassified_shipped_fitted_of": list(misfits),
            "efficiency": efficiency, "access_intensity": intensity,
            "interference_airtime_weighting": weighting, "collision_time_ratio": ratio, "fit_loss": loss,
            **report})
    return 0


def _write_json(path: Path, document: dict) -> None:
    tmp_out = path.with_suffix(".tmp")
    tmp_out.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp_out, path)


def _pm(values: np.ndarray) -> str:
    return f"{values.mean():.1f} ± {values.std():.1f}"


def _report(rows: list[tuple[dict, ModelScene, ModelScene]], ns3: dict[str, Ns3Scene]) -> dict:
    """Print the table and the held-out verdicts; return them as a dict."""
    print("\n| scene | split | APs x stations | ns-3 total Mbps (mean ± sd, seeds) | model | error "
          "| before | error before | per-AP ns-3 / model Mbps | worst AP error / bound "
          "| station median error |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    held: dict[str, list] = {"ap": [], "ap_agree": [], "scene": [], "station": []}
    every: dict[str, list] = {"scene": [], "scene_before": [], "ap": [], "ap_before": [], "lost": []}
    scenes_out = []
    for scene, model, before in rows:
        result = ns3[scene["name"]]
        totals = result.ap_mbps.sum(axis=1)
        error = scene_error(model, result)
        aps = ap_errors(model, result)
        aps_before = ap_errors(before, result)
        every["scene"].append(abs(error))
        every["scene_before"].append(abs(scene_error(before, result)))
        every["ap"] += aps.tolist()
        every["ap_before"] += aps_before.tolist()
        lost = np.flatnonzero((aps_before <= 1.0) & (aps > 1.0))
        every["lost"] += [f"{scene['name']} AP {k}" for k in lost]
        stations = station_errors(model, result)
        median = float(np.median(stations)) if stations.size else float("nan")
        per_ap = ", ".join(f"{n:.0f}/{m:.0f}" for n, m in zip(result.ap_mbps.mean(axis=0), model.ap_mbps,
                                                                strict=True))
        if len(per_ap) > 60:
            per_ap = per_ap[:57] + "..."
        print(f"| {scene['name']} | {scene['split']} | {len(scene['uavs_m'])} x {len(scene['users_m'])} | "
              f"{_pm(totals)} | {model.ap_mbps.sum():.1f} | {100 * error:+.1f} % | "
              f"{before.ap_mbps.sum():.1f} | {100 * scene_error(before, result):+.1f} % | {per_ap} | "
              f"{aps.max():.2f} | "
              f"{f'{100 * median:.0f} %' if stations.size else '-'} ({stations.size}) |")
        if scene["split"] == "test":
            held["ap"] += aps.tolist()
            ap_mean = result.ap_mbps.mean(axis=0)
            agree = result.ap_mbps.std(axis=0) <= SEEDS_AGREE_CV * np.maximum(ap_mean, 1e-9)
            held["ap_agree"] += aps[agree].tolist()
            held["scene"].append(abs(error))
            held["station"] += stations.tolist()
        scenes_out.append({"name": scene["name"], "split": scene["split"],
                           "ns3_total_mbps": [float(totals.mean()), float(totals.std())],
                           "ns3_ap_mbps": result.ap_mbps.mean(axis=0).tolist(),
                           "model_ap_mbps": model.ap_mbps.tolist(),
                           "before_model_ap_mbps": before.ap_mbps.tolist(),
                           "scene_error": error, "worst_ap_error_over_bound": float(aps.max()),
                           "station_median_error": median, "ns3_wall_s": result.wall_s})
    ap = np.asarray(held["ap"])
    print(f"\nheld out: {int(np.sum(ap <= 1.0))} / {ap.size} APs within their bound (worst "
          f"{ap.max():.2f} of it); scene totals within 10 %: "
          f"{sum(e <= SCENE_TOLERANCE for e in held['scene'])} / {len(held['scene'])} "
          f"(worst {100 * max(held['scene']):.1f} %); APs whose seeds agree (CV <= 10 %): "
          f"{sum(e <= 1.0 for e in held['ap_agree'])} / {len(held['ap_agree'])} within their bound; "
          f"station median relative error "
          f"{100 * np.median(held['station']):.1f} % over {len(held['station'])} stations whose seeds agree")
    within = sum(e <= SCENE_TOLERANCE for e in every["scene"])
    within_before = sum(e <= SCENE_TOLERANCE for e in every["scene_before"])
    aps_within = sum(e <= 1.0 for e in every["ap"])
    aps_within_before = sum(e <= 1.0 for e in every["ap_before"])
    print(f"every scene: totals within 10 % {within} / {len(rows)} (before {within_before}); APs within "
          f"their bound {aps_within} / {len(every['ap'])} (before {aps_within_before}); within before, "
          f"outside now: {', '.join(every['lost']) or 'none'}")
    sharing = _sharing(rows, ns3)
    return {"every_scene": {"scene_within": within, "scene_within_before": within_before,
                            "aps_within": aps_within, "aps_within_before": aps_within_before,
                            "aps": len(every["ap"]), "within_before_outside_now": every["lost"]},
            "held_out": {"aps_within": int(np.sum(ap <= 1.0)), "aps": int(ap.size),
                         "agreeing_aps_within": sum(e <= 1.0 for e in held["ap_agree"]),
                         "agreeing_aps": len(held["ap_agree"]),
                         "worst_ap_over_bound": float(ap.max()),
                         "scene_within": int(sum(e <= SCENE_TOLERANCE for e in held["scene"])),
                         "scenes": len(held["scene"]), "worst_scene_error": float(max(held["scene"])),
                         "station_median_error": float(np.median(held["station"]))},
            "sharing": sharing, "scenes": scenes_out}


def _sharing(rows: list[tuple[dict, ModelScene, ModelScene]], ns3: dict[str, Ns3Scene]) -> list[dict]:
    """Co-channel sharing and channel separation: the pairs on one channel against the same pairs on two."""
    found = {scene["name"]: (scene, model) for scene, model, _ in rows}
    out = []
    for d_m in (5, 20, 60):
        one, two = f"pair-co-{d_m}m", f"pair-2ch-{d_m}m"
        if one in found and two in found:
            n_ratio = ns3[one].ap_mbps.sum(axis=1).mean() / ns3[two].ap_mbps.sum(axis=1).mean()
            m_ratio = found[one][1].ap_mbps.sum() / found[two][1].ap_mbps.sum()
            print(f"pair {d_m} m: one channel / two channels = ns-3 {n_ratio:.2f}, model {m_ratio:.2f}")
            out.append({"distance_m": d_m, "ns3_ratio": float(n_ratio), "model_ratio": float(m_ratio)})
    return out


if __name__ == "__main__":
    sys.exit(main())
