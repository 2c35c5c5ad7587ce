#!/usr/bin/env bash
# One-shot check of the CUDA engine (numba-cuda) on a lent GPU (an H200): the CUDA test module
# on cuda:0 with 100 random robots, then the throughput bench (100, 1,000 and 10,000 paper-like
# 7^3 robots, land and water, float64, beside the numba engine on all cores). Installs nothing
# from the network: it needs a Python that already has numba, numba-cuda, numpy, scipy and
# pytest (PYTHON, default python3; the lent machine's image has them, but not softevo, warp
# or trimesh). softevo itself comes from this checkout: an offline editable install, or, if
# pip cannot do that, a path finder of its own (softevo's folders map to its subpackages through
# pyproject.toml's package-dir, so PYTHONPATH alone does not find softevo.sim). Every part
# has its own time limit; the whole script stays under 4 minutes. Output: stdout, and
# $OUT/gpu_check/ (or ./gpu_check/) for the logs.
#
#   bash bench/gpu_device_check.sh                 # DEVICE=cuda:0, ROBOTS=100
#   TEST_LIMIT=100 BENCH_LIMIT=110 STEPS=1000 MODULI=1e6 bash bench/gpu_device_check.sh
set -uo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
DEVICE=${DEVICE:-cuda:0}
ROBOTS=${ROBOTS:-100}              # SOFTEVO_CUDA_RANDOM_ROBOTS of the test module
TEST_LIMIT=${TEST_LIMIT:-120}      # seconds (the CPU and GPU kernels compile first)
BENCH_LIMIT=${BENCH_LIMIT:-100}    # seconds
STEPS=${STEPS:-1000}               # bench steps per robot per case
MODULI=${MODULI:-1e6}              # bench stiffnesses, Pa (1e6,1e7 doubles its time)
LOGS=${OUT:-.}/gpu_check
mkdir -p "$LOGS"
export PYTHONUNBUFFERED=1
say() { printf '\n=== %s (%s)\n' "$*" "$(date -u +%H:%M:%S)"; }

say "environment"
timeout 20 nvidia-smi 2>&1 | tee "$LOGS/nvidia-smi.txt" | head -25
if ! "$PY" -c "import numba, numba_cuda, numpy, scipy, pytest" 2>/dev/null; then
  echo "missing: $PY lacks numba, numba-cuda, numpy, scipy or pytest (pip install 'softevo[gpu]' pytest)"; exit 3
fi
timeout 60 "$PY" - <<'EOF' 2>&1 | tee "$LOGS/versions.txt"
import platform

import numba
import numba_cuda
import numpy
import scipy
from numba import cuda

print(f"python {platform.python_version()}, numba {numba.__version__}, numba-cuda {numba_cuda.__version__}, "
      f"numpy {numpy.__version__}, scipy {scipy.__version__}")
print(f"cuda available: {cuda.is_available()}; simulator: {bool(numba.config.ENABLE_CUDASIM)}")
if cuda.is_available() and not numba.config.ENABLE_CUDASIM:
    for gpu in cuda.gpus:
        name = gpu.name.decode() if isinstance(gpu.name, bytes) else gpu.name
        print(f"  {gpu.id}: {name}, compute capability {gpu.compute_capability}")
    try:
        print(f"  CUDA runtime {cuda.runtime.get_version()}")
    except Exception as exc:  # the versions are for the log only
        print(f"  CUDA runtime version unknown: {exc}")
EOF

say "softevo from this checkout"
if "$PY" -c "import softevo.sim" 2>/dev/null; then
  echo "softevo.sim already importable"
elif "$PY" -m pip install -q --no-index --no-deps --no-build-isolation -e . >"$LOGS/install.log" 2>&1 \
    && "$PY" -c "import softevo.sim" 2>>"$LOGS/install.log"; then
  echo "installed offline (editable; see $LOGS/install.log)"
else
  # A sitecustomize on PYTHONPATH that maps softevo and softevo.<x> to their folders (the
  # package-dir of pyproject.toml), ahead of the image's own sitecustomize, which it then runs.
  shim=$(mktemp -d)
  "$PY" - "$shim" "$PWD" <<'EOF'
import sys
import tomllib
from pathlib import Path

shim, root = Path(sys.argv[1]), Path(sys.argv[2])
dirs = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
mapping = {name: str(root / folder) for name, folder in dirs.items()}
(shim / "sitecustomize.py").write_text(f'''\
import importlib.machinery, importlib.util, os, sys
_MAP = {mapping!r}
class _SoftevoFinder:
    @staticmethod
    def find_spec(name, path=None, target=None):
        folder = _MAP.get(name)
        if folder is None:
            return None
        return importlib.util.spec_from_file_location(
            name, os.path.join(folder, "__init__.py"), submodule_search_locations=[folder])
sys.meta_path.insert(0, _SoftevoFinder)
_here = os.path.dirname(os.path.abspath(__file__))
_other = importlib.machinery.PathFinder.find_spec(
    "sitecustomize", [p for p in sys.path if os.path.abspath(p or ".") != _here])
if _other is not None and _other.loader is not None:
    _other.loader.exec_module(importlib.util.module_from_spec(_other))
''')
EOF
  export PYTHONPATH="$shim${PYTHONPATH:+:$PYTHONPATH}"
  if "$PY" -c "import softevo.sim" 2>>"$LOGS/install.log"; then
    echo "pip could not install offline (see $LOGS/install.log); softevo found through $shim/sitecustomize.py"
  else
    echo "softevo.sim does not import (see $LOGS/install.log)"; tail -5 "$LOGS/install.log"; exit 3
  fi
fi
"$PY" -c "import softevo.sim, softevo.sim.numba_engine; from softevo.sim import cuda_engine; print('softevo.sim:', softevo.sim.__file__)" 2>&1 \
  | tail -3

say "CUDA test module on $DEVICE, $ROBOTS random robots (limit $TEST_LIMIT s)"
SOFTEVO_CUDA_TEST_DEVICE=$DEVICE SOFTEVO_CUDA_RANDOM_ROBOTS=$ROBOTS SOFTEVO_AGREEMENT_JSON="$LOGS/agreement.json" \
  timeout -k 5 "$TEST_LIMIT" "$PY" -m pytest tests/sim/test_cuda_engine.py -q -p no:cacheprovider --durations=5 \
  2>&1 | tee "$LOGS/tests.log" \
  | grep -E "passed|failed|error|Error|ERROR|skipped|cuda\.|s call|s setup" | head -30
echo "tests: exit ${PIPESTATUS[0]} (124: stopped at $TEST_LIMIT s)"

say "throughput bench on $DEVICE: 100, 1,000, 10,000 robots, land and water, float64 and mixed (limit $BENCH_LIMIT s)"
timeout -k 5 "$BENCH_LIMIT" "$PY" bench/gpu_throughput.py --device "$DEVICE" --batches 100,1000,10000 \
  --max-batch 10000 --steps "$STEPS" --numba-max-batch 100 --worlds land,water --moduli "$MODULI" \
  --precisions float64,mixed 2>&1 | tee "$LOGS/bench.txt"
echo "bench: exit ${PIPESTATUS[0]} (124: stopped at $BENCH_LIMIT s)"
say "done"
