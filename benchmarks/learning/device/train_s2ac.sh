#!/usr/bin/env bash
# The strategy-2 admission-control network on a lent GPU machine, in one command (device tool):
# 10,000 crowds of the capacitated expert on every CPU core, then training on the GPU (bfloat16).
# Usage: OUT=<folder> bash benchmarks/learning/device/train_s2ac.sh [N_SCENES] [DATASET_BUDGET_S] [TRAIN_BUDGET_S] [DEVICE]
# Writes $OUT/run/{best.pt,checkpoint.pt,history.png}, $OUT/log-*.txt. Never used by CI or the tests.
set -uo pipefail
n="${1:-10000}"; data_budget="${2:-390}"; train_budget="${3:-150}"; device="${4:-cuda}"
export PYTHONUNBUFFERED=1 PYTHONPATH="$PWD"
cli() { python3 -c "import sys; from uav_swarm.cli import main; sys.exit(main(sys.argv[1:]))" "$@"; }
nproc; python3 -c "import torch, numpy, scipy; print(torch.__version__, torch.cuda.is_available(), numpy.__version__)"
start=$(date +%s)
timeout "$data_budget" bash -c "$(declare -f cli); cli dataset --task wifi-s2 --config configs/tasks/wifi-s2-ac.toml \
    --out data/s2ac-train --n $n --seed 0 --workers $(nproc)" > "$OUT/log-dataset.txt" 2>&1
echo "dataset exit $? after $(( $(date +%s) - start )) s"; tail -c 600 "$OUT/log-dataset.txt"
if [ ! -f data/s2ac-train/manifest.json ]; then echo "no complete dataset"; exit 1; fi
timeout "$train_budget" bash -c "$(declare -f cli); cli train --task wifi-s2 --config configs/tasks/wifi-s2-ac.toml \
    --out '$OUT/run' --data data/s2ac-train --device $device --precision auto --torch-threads 8" \
    > "$OUT/log-train.txt" 2>&1
echo "train exit $? after $(( $(date +%s) - start )) s"; grep -o "INFO learning.train: epoch.*" "$OUT/log-train.txt" | tail -n 40
ls -la "$OUT/run"
