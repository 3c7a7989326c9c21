"""Capacity curves: validation score against samples and wall time for training runs side by side.

    python benchmarks/learning/capacity_curves.py --out curves.csv w16d3=runs/w16d3 w32d3=runs/w32d3
        w16d4=runs/w16d4

Reads each run folder's ``checkpoint.pt`` (``uav-swarm train`` writes it after every epoch, with the
history of the run and the network's shape), and writes one CSV row per (run, epoch): samples seen,
training seconds (validation included), validation loss, corr, precision and their sum (the score
``train`` keeps its best checkpoint by). Prints a Markdown table of the curves at equal samples (one
column per run) and each run's best epoch.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

from learning.checkpoint import load_checkpoint

FIELDS = ("run", "width", "depth", "epoch", "samples", "elapsed_s", "val_loss", "val_corr", "val_precision",
          "score")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="NAME=FOLDER of each training run")
    parser.add_argument("--out", required=True, help="CSV file written")
    args = parser.parse_args()
    curves: dict[str, list[dict[str, float]]] = {}
    rows: list[dict[str, object]] = []
    for spec in args.runs:
        name, sep, folder = spec.partition("=")
        if not sep:
            parser.error(f"{spec!r}: expected NAME=FOLDER")
        ckpt = load_checkpoint(Path(folder) / "checkpoint.pt")
        history, config = ckpt.payload["history"], ckpt.model_config
        curves[name] = [{k: float(v) for k, v in h.items() if isinstance(v, (int, float))} for h in history]
        for h in curves[name]:
            rows.append({"run": name, "width": config.width, "depth": config.depth, "epoch": int(h["epoch"]),
                         "samples": int(h["samples"]), "elapsed_s": round(h["elapsed_s"], 1),
                         "val_loss": h["val_loss"], "val_corr": h["val_corr"],
                         "val_precision": h["val_precision"],
                         "score": h["val_corr"] + h["val_precision"]})
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(out.suffix + ".tmp")
    with tmp.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(out)
    print("| samples | " + " | ".join(f"{n}: corr / precision % (s)" for n in curves) + " |")
    print("|---" * (len(curves) + 1) + "|")
    for samples in sorted({h["samples"] for curve in curves.values() for h in curve}):
        cells = []
        for curve in curves.values():
            hit = [h for h in curve if h["samples"] == samples]
            cells.append(f"{100 * hit[0]['val_corr']:.1f} / {100 * hit[0]['val_precision']:.1f} "
                         f"({hit[0]['elapsed_s']:.0f})" if hit else "")
        print(f"| {int(samples):,} | " + " | ".join(cells) + " |")
    for name, curve in curves.items():
        if curve:
            best = max(curve, key=lambda h: h["val_corr"] + h["val_precision"])
            print(f"{name}: best epoch {int(best['epoch'])} ({int(best['samples']):,} samples): corr "
                  f"{100 * best['val_corr']:.1f}, precision {100 * best['val_precision']:.1f}")

if __name__ == "__main__":
    main()
