"""Compile the cuda engine's kernels to PTX for an H100/H200 (sm_90) on a machine without a
GPU: numba-cuda's real compiler (type inference, NVVM), not its simulator, so a kernel that
the simulator runs but the GPU would refuse fails here first.

Usage: python bench/cuda_compile_check.py [--cc 9.0] [--threads 256]

Needs NVVM and libdevice (``pip install 'numba-cuda[cu13]'``; not in the lock, and not
needed by CI). Prints, per kernel (each precision, state in shared or in global memory), its
PTX size and the count of double- and single-precision FMA instructions, and fails if a
kernel does not compile.
With ptxas too (``pip install nvidia-cuda-nvcc``, or on PATH) it assembles the PTX and
prints the registers, spills and stack per thread: what bounds the blocks per multiprocessor.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from types import SimpleNamespace

if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1":
    sys.exit("error: unset NUMBA_ENABLE_CUDASIM: this checks the real compiler")

import numba  # noqa: E402
import numba.cuda.dispatcher as dispatcher  # noqa: E402
from numba import cuda  # noqa: E402

from softevo.sim import cuda_engine, cuda_kernels  # noqa: E402
from softevo.sim.models import PRECISIONS  # noqa: E402
from softevo.sim.scene import parse_scene  # noqa: E402
from softevo.sim.system import build_robot, pack  # noqa: E402
from softevo.sim.worlds import WATER  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cc", default="9.0", help="compute capability, e.g. 9.0")
    parser.add_argument("--threads", type=int, default=cuda_engine.THREADS["gpu"])
    args = parser.parse_args()
    cc = tuple(int(x) for x in args.cc.split("."))
    # device functions ask the current device for its compute capability: there is none here
    dispatcher.get_current_device = lambda: SimpleNamespace(compute_capability=cc)
    scenes = [{"body": [[[1, 2], [2, 1]]], "environment": {"kind": WATER.name},
               "model": "voxcad-land-water", "self_collisions": True, "record": {"every": 10}}]
    batch, state = pack([build_robot(parse_scene(s)) for s in scenes])
    host = cuda_engine.kernel_inputs(batch, state)
    which = host[0].voff[:1]  # the kernel's groups (``cuda_kernels.Robots`` ...) as typed tuples
    sig = tuple(numba.typeof(x) for x in (numba.int32(1), which, *host))
    for precision in PRECISIONS:
        for shared in (True, False):
            kernel = cuda_kernels.rollout_kernel(shared, args.threads, precision)
            ptx, _ = cuda.compile_ptx(kernel.py_func, sig, cc=cc)
            print(f"rollout {precision} shared={shared}: {len(ptx) / 1e3:.0f} kB of PTX, "
                  f"{ptx.count('fma.rn.f64')} fma.rn.f64, {ptx.count('fma.rn.f32')} fma.rn.f32, "
                  f"{ptx.count('bar.sync')} bar.sync")
        lines = [assemble(ptxas, ptx, cc) for ptxas in find_ptxas()]
        ok = [line for line in lines if not line.startswith("ptxas failed")]
        if ok or lines:
            print("  " + (ok or lines)[0])


def find_ptxas() -> list[str]:
    """The ptxas on PATH and those of nvidia-cuda-nvcc wheels (the newest CUDA first)."""
    found = [shutil.which("ptxas")] if shutil.which("ptxas") else []
    try:
        import nvidia
    except ImportError:
        return found
    for root in nvidia.__path__:
        found += [str(p) for p in sorted(Path(root).glob("*/bin/ptxas"), reverse=True)]
    return found


def assemble(ptxas: str, ptx: str, cc: tuple[int, int]) -> str:
    """ptxas's resource line for the kernel: registers, spills, stack."""
    with tempfile.TemporaryDirectory() as folder:
        source = Path(folder) / "kernel.ptx"
        source.write_text(ptx)
        out = subprocess.run([ptxas, f"-arch=sm_{cc[0]}{cc[1]}", "-v", str(source), "-o",
                              str(Path(folder) / "kernel.cubin")], capture_output=True, text=True)
    if out.returncode:
        return "ptxas failed: " + " | ".join(out.stderr.strip().splitlines()[:3])
    used = re.findall(r"Used (\d+) registers", out.stderr)
    spills = re.findall(r"(\d+) bytes spill stores, (\d+) bytes spill loads", out.stderr)
    stack = re.findall(r"(\d+) bytes stack frame", out.stderr)
    return (f"ptxas sm_{cc[0]}{cc[1]}: {used[-1] if used else '?'} registers per thread, "
            f"spills {'/'.join(spills[0]) if spills else '?'} bytes (stores/loads), "
            f"stack {stack[0] if stack else '?'} bytes")


if __name__ == "__main__":
    main()
