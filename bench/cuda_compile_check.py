"""Compile the cuda engine's kernels to PTX for an H100/H200 (sm_90) on a machine without a
GPU: numba-cuda's real compiler (type inference, NVVM), not its simulator, so a kernel that
the simulator runs but the GPU would refuse fails here first.

Usage: python bench/cuda_compile_check.py [--cc 9.0] [--threads 256]

Needs NVVM and libdevice (``pip install 'numba-cuda[cu13]'``; not in the lock, and not
needed by CI). Prints, per kernel (state in shared or in global memory), its PTX size and
the count of double-precision FMA instructions, and fails if a kernel does not compile.
"""

from __future__ import annotations

import argparse
import os
import sys
from types import SimpleNamespace

if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1":
    sys.exit("error: unset NUMBA_ENABLE_CUDASIM: this checks the real compiler")

import numba  # noqa: E402
import numba.cuda.dispatcher as dispatcher  # noqa: E402
from numba import cuda  # noqa: E402

from softevo.sim import cuda_engine, cuda_kernels  # noqa: E402
from softevo.sim.scene import parse_scene  # noqa: E402
from softevo.sim.system import build_robot, pack  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cc", default="9.0", help="compute capability, e.g. 9.0")
    parser.add_argument("--threads", type=int, default=cuda_engine.THREADS["gpu"])
    args = parser.parse_args()
    cc = tuple(int(x) for x in args.cc.split("."))
    # device functions ask the current device for its compute capability: there is none here
    dispatcher.get_current_device = lambda: SimpleNamespace(compute_capability=cc)
    scenes = [{"body": [[[1, 2], [2, 1]]], "environment": {"kind": "water"},
               "model": "voxcad-land-water", "self_collisions": True, "record": {"every": 10}}]
    batch, state = pack([build_robot(parse_scene(s)) for s in scenes])
    host = cuda_engine.kernel_inputs(batch, state)
    which = host["voff"][:1]
    sig = tuple(numba.typeof(x) for x in (numba.int32(1), which, *host.values()))
    for shared in (True, False):
        kernel = cuda_kernels.rollout_kernel(shared, args.threads)
        ptx, _ = cuda.compile_ptx(kernel.py_func, sig, cc=cc)
        print(f"rollout shared={shared}: {len(ptx) / 1e3:.0f} kB of PTX, "
              f"{ptx.count('fma.rn.f64')} fma.rn.f64, {ptx.count('bar.sync')} bar.sync")


if __name__ == "__main__":
    main()
