#!/usr/bin/env bash
# One-shot check of the Warp engine on a CUDA GPU (an H200 when one is lent): the Warp test
# module on cuda:0, the throughput bench and the float32 accuracy check. Installs nothing
# from the internet: it needs a Python with softevo's dependencies and warp-lang already
# there (PYTHON, default python3); softevo itself is installed from this checkout without
# the network if it is not importable. Every part has its own time limit; the whole script
# stays under 8 minutes. Output: stdout, and $OUT/gpu_check/ (or ./gpu_check/) for the logs.
set -uo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
DEVICE=${DEVICE:-cuda:0}
LOGS=${OUT:-.}/gpu_check
mkdir -p "$LOGS"
say() { printf '\n=== %s (%s)\n' "$*" "$(date -u +%H:%M:%S)"; }

say "environment"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>&1 | head -2
if ! "$PY" -c "import numba, scipy, warp" 2>/dev/null; then
  echo "missing: $PY lacks numba, scipy or warp-lang (pip install 'softevo[gpu]' beforehand)"; exit 3
fi
if ! "$PY" -c "import softevo.sim" 2>/dev/null; then
  "$PY" -m pip install -q --no-index --no-deps --no-build-isolation -e . >"$LOGS/install.log" 2>&1 \
    || { echo "could not install softevo offline (see $LOGS/install.log)"; exit 3; }
fi
"$PY" -c "import warp as wp; wp.init(); print('warp', wp.__version__, [str(d) for d in wp.get_devices()])"

say "Warp test module on $DEVICE (limit 120 s)"
SOFTEVO_WARP_TEST_DEVICE=$DEVICE SOFTEVO_AGREEMENT_JSON="$LOGS/agreement.json" \
  timeout 120 "$PY" -m pytest tests/sim/test_warp_engine.py -q -p no:cacheprovider --durations=5 \
  2>&1 | tee "$LOGS/tests.log" | grep -E "passed|failed|error|warp\.(trajectory\.worst|random)|s call" | head -20

say "throughput bench on $DEVICE (limit 200 s)"
timeout 200 "$PY" bench/gpu_throughput.py --device "$DEVICE" --max-batch 10000 --steps 1000 \
  --numba-max-batch 100 2>&1 | tee "$LOGS/bench.txt"

say "float32 accuracy: 100 whole evaluations per world and stiffness (limit 120 s)"
timeout 120 "$PY" bench/gpu_throughput.py --device "$DEVICE" --max-batch 1 --steps 10 \
  --numba-max-batch 0 --accuracy 100 2>&1 | grep -E "^accuracy|device" | tee "$LOGS/accuracy.txt"
say "done"
