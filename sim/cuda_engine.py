"""The GPU engine: ``simulate_many`` on an NVIDIA GPU through numba-cuda, the same scenes and
the same ``Result`` (``sim.result``) as the numba engine (``sim.numba_engine``).

Scenes go through the one scene -> arrays path (``prepare``, ``pack``); the packed batch is
copied to the device once and ``sim.cuda_kernels`` steps it, one thread block per robot, up
to ``chunk`` steps per launch; between launches the host only asks which robots still run.
A robot whose state fits in a block's shared memory runs there, a larger one on the global
arrays (the same kernel source, built for each). Every model and option of the CPU engine
is supported (the physics is the same code, ``sim.physics``).

Precision: each scene's ``model_options.precision`` (``sim.models.PRECISIONS``): float64, or
"mixed", whose links compute in float32 (``cuda_kernels.LINK_FORCES``); a batch of both runs
as one launch series per precision. numba-cuda is imported on first use only.
``NUMBA_ENABLE_CUDASIM=1`` (set before anything imports ``numba.cuda``) runs the same kernels
on numba-cuda's simulator, in Python, on any machine: slow, for small robots. Without
numba-cuda, or without the device asked for, ``EngineUnavailable`` says so in one line.
"""

from __future__ import annotations

import os
import sys
import time
from types import SimpleNamespace
from typing import Any

import numpy as np

from .engines import EngineUnavailable
from .models import PRECISIONS
from .physics import COLLIDE_MARGIN
from .result import Result, from_run, prepare
from .scene import Scene
from .system import F_L, I_N_FRAMES, I_STEPS, MAX_CONTACTS, pack

DEFAULT_DEVICE = "cuda:0"
CHUNK_STEPS = 5000  # steps per launch on a GPU (a 7^3 robot: a few milliseconds)
THREADS = {"gpu": 256, "simulator": 4}  # threads per block (SOFTEVO_CUDA_THREADS overrides)
SHARED_DEFAULT = 48 * 1024  # bytes of shared memory a block may use without opting in
SIMULATOR_SWITCH_SECONDS = 5e-5  # the GIL's switch interval while the simulator runs (5x faster)


def cuda_module():
    """numba-cuda's ``cuda`` module; ``EngineUnavailable`` if numba-cuda is missing."""
    try:
        import numba.cuda as cuda
        from numba.cuda import config  # noqa: F401 (numba-cuda, not numba's deprecated built-in target)
    except ImportError:
        raise EngineUnavailable(
            "the cuda engine needs the numba-cuda package: pip install 'softevo[gpu]'") from None
    return cuda


def simulator() -> bool:
    """Whether numba-cuda runs on its simulator in this process (NUMBA_ENABLE_CUDASIM=1)."""
    cuda_module()
    from numba.cuda import config

    return bool(config.ENABLE_CUDASIM)


def device_of(name: str | None):
    """The CUDA device called ``name`` ("cuda:N", default ``DEFAULT_DEVICE``), selected for this
    thread; ``EngineUnavailable`` naming what there is if it does not exist here."""
    cuda = cuda_module()
    name = name or DEFAULT_DEVICE
    if not name.startswith("cuda:") or not name[5:].isdigit():
        raise EngineUnavailable(f"device: the cuda engine takes cuda:N (got {name!r})")
    number = int(name[5:])
    try:
        available = cuda.is_available()
        count = len(cuda.gpus) if available else 0
    except Exception:  # a driver that fails to load is as good as none
        available, count = False, 0
    if not available:
        raise EngineUnavailable(
            "device: no CUDA GPU here (numba-cuda finds no driver or device); set "
            "NUMBA_ENABLE_CUDASIM=1 to run the cuda engine on numba-cuda's simulator")
    if number >= count:
        raise EngineUnavailable(
            f"device: no CUDA device {name!r} here; there are: "
            + ", ".join(f"cuda:{k}" for k in range(count)))
    return cuda.select_device(number)


def simulate_many(scenes: list[dict | Scene], device: str | None = None,
                  chunk: int | None = None) -> list[Result]:
    """Simulate many robots in one batch on a CUDA device (one per precision of their
    ``model_options.precision``); results in the order of ``scenes``. ``chunk``: steps per
    launch (default ``CHUNK_STEPS``; the simulator runs a batch in one launch)."""
    dev = device_of(device)
    parsed, robots, results, runnable = prepare(scenes)
    groups: dict[str, list[int]] = {}
    for k in runnable:
        groups.setdefault(parsed[k].options.precision, []).append(k)
    for precision, members in groups.items():
        out = run_batch([robots[k] for k in members], dev, precision, chunk)
        for r, k in enumerate(members):
            results[k] = from_run(parsed[k], robots[k], 0, *out.robot(r))
    return results  # type: ignore[return-value]


class BatchOutput:
    """What a run leaves on the host, cut per robot in ``robot(r)`` as ``sim.result.from_run``
    takes it (a one-robot batch), and the seconds its step loop took."""

    def __init__(self, seconds, voff, froff, n_frames, pos, frames, com_traj, com_count,
                 status, done):
        self.seconds = seconds  # wall time of the launches alone (arrays already on the device)
        self.voff, self.froff, self.n_frames = voff, froff, n_frames
        self.pos, self.frames, self.com_traj = pos, frames, com_traj
        self.com_count, self.status, self.done = com_count, status, done

    @property
    def voxel_steps(self) -> float:
        """Voxel-steps the run stepped: each robot's steps times its voxels."""
        return float(np.sum(self.done * np.diff(self.voff)))

    def robot(self, r: int) -> tuple[Any, ...]:
        v0, v1 = self.voff[r], self.voff[r + 1]
        n = v1 - v0
        f0, nf = self.froff[r], self.n_frames[r]
        frames = self.frames[f0: f0 + nf * n].reshape(nf, n, 3)
        return (
            SimpleNamespace(voff=np.array([0, n])),
            SimpleNamespace(pos=self.pos[v0:v1]),
            frames,
            self.com_traj[r: r + 1],
            self.com_count[r: r + 1],
            self.status[r: r + 1],
            self.done[r: r + 1],
        )


def _offsets(counts) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


def threads_per_block() -> int:
    """Threads per block: ``SOFTEVO_CUDA_THREADS``, else ``THREADS`` for the GPU or the
    simulator."""
    text = os.environ.get("SOFTEVO_CUDA_THREADS")
    if text:
        if not text.isdigit() or not 1 <= int(text) <= 1024:
            raise EngineUnavailable(f"SOFTEVO_CUDA_THREADS: must be 1..1024 (got {text!r})")
        return int(text)
    return THREADS["simulator" if simulator() else "gpu"]


def shared_bytes(n_voxels: int, n_links: int) -> int:
    """Bytes of shared memory a robot's state takes (``sim.cuda_kernels`` layout)."""
    from .cuda_kernels import LINK_WORDS, VOXEL_WORDS

    return 8 * (VOXEL_WORDS * n_voxels + LINK_WORDS * n_links)


def _shared_limit(kernel, dev, want: int) -> int:
    """The shared memory a block of ``kernel`` may use on ``dev``: up to ``want`` bytes when
    the device lets a kernel opt in beyond the default, else ``SHARED_DEFAULT``."""
    optin = int(getattr(dev, "MAX_SHARED_MEMORY_PER_BLOCK_OPTIN", SHARED_DEFAULT))
    if want <= SHARED_DEFAULT or optin <= SHARED_DEFAULT:
        return SHARED_DEFAULT
    try:  # raise the kernel's dynamic shared memory cap (cuFuncSetAttribute)
        from numba.cuda.cudadrv import driver
        from numba.cuda.cudadrv.driver import binding

        if not kernel.overloads:
            return SHARED_DEFAULT
        for overload in kernel.overloads.values():
            fn = overload._codelibrary.get_cufunc()
            attr = binding.CUfunction_attribute.CU_FUNC_ATTRIBUTE_MAX_DYNAMIC_SHARED_SIZE_BYTES
            driver.driver.cuKernelSetAttribute(attr, min(want, optin), fn.handle, dev.id)
        return min(want, optin)
    except Exception:  # an older driver binding: the robots that do not fit run in global memory
        return SHARED_DEFAULT


def kernel_inputs(batch, state) -> tuple:
    """The rollout kernel's arguments after ``chunk`` and ``which``: its groups
    (``cuda_kernels.Robots``, ``VoxelData``, ``LinkData``, ``ContactData``, ``MeshData``,
    ``BodyState``, ``Scratch``, ``Output``) of host arrays (flat, int32 indices: the
    ``sim.cuda_kernels`` layout), for a packed batch at its initial state."""
    from . import cuda_kernels as ck

    R = len(batch.voff) - 1
    voff, loff, soff, moff, foff = batch.voff, batch.loff, batch.soff, batch.moff, batch.foff
    n_vox, n_links = int(voff[-1]), int(loff[-1])
    counts = np.diff(voff)
    froff = _offsets(batch.iparams[:, I_N_FRAMES].astype(np.int64) * counts)
    if batch.iparams[:, I_STEPS].max(initial=0) >= 2**31 or froff[-1] * 3 >= 2**31:
        raise EngineUnavailable("batch too large for the cuda engine's int32 counters: split it")
    # each voxel's facets (the mesh lists them voxel by voxel, indices local to the robot)
    # and its place on the surface
    face_voxel = batch.mesh_face[:, 3] + np.repeat(voff[:-1], np.diff(foff))
    fstart = np.searchsorted(face_voxel, np.arange(n_vox), side="left")
    fcount = np.searchsorted(face_voxel, np.arange(n_vox), side="right") - fstart
    fstart = fstart - np.repeat(foff[:-1], counts)
    surf_of = -np.ones(n_vox, dtype=np.int64)
    first_surface = np.repeat(soff[:-1], np.diff(soff))
    surf_of[batch.surface + np.repeat(voff[:-1], np.diff(soff))] = (
        np.arange(len(batch.surface)) - first_surface)
    no_link = np.diff(loff)[np.repeat(np.arange(R), counts)][:, None]  # ``Robot.vlink``'s mark
    vlink = np.where(batch.vlink == no_link, -1, batch.vlink)
    ctl = np.zeros((R, ck.N_CTL), dtype=np.int32)
    ctl[:, ck.C_RUNNING] = 1
    ctl[:, ck.C_DONE] = batch.iparams[:, I_STEPS]

    def f64(x):
        x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
        return x if x.size else np.zeros(1)

    def i32(x):
        x = np.ascontiguousarray(x, dtype=np.int32).reshape(-1)
        return x if x.size else np.zeros(1, np.int32)

    return (
        ck.Robots(f64(batch.fparams), i32(batch.iparams), i32(voff), i32(loff), i32(soff),
                  i32(moff), i32(foff), i32(froff)),
        ck.VoxelData(i32(batch.flags), f64(batch.cos_phase), f64(batch.sin_phase),
                     f64(batch.phase), f64(batch.vconst), f64(batch.ext_force), i32(vlink),
                     i32(batch.exposed), i32(fstart), i32(fcount), i32(surf_of)),
        ck.LinkData(i32(batch.link_neg), i32(batch.link_pos), i32(batch.link_axis),
                    f64(batch.link_stiff), f64(batch.link_damp)),
        ck.ContactData(i32(batch.surface), i32(batch.near), i32([batch.near.shape[1]]),
                       i32(np.zeros(MAX_CONTACTS * len(batch.surface))),
                       i32(np.zeros(len(batch.surface))),
                       f64(np.full(3 * len(batch.surface), np.nan))),
        ck.MeshData(i32(batch.mesh_vert), i32(batch.mesh_face),
                    f64(np.zeros(3 * len(batch.mesh_vert)))),
        ck.BodyState(f64(state.pos), f64(state.quat), f64(state.lin_mom), f64(state.ang_mom),
                     i32(np.ones(n_vox)), f64(np.zeros(n_links * ck.LINK_STATE))),
        ck.Scratch(f64(np.zeros(n_vox)), f64(np.zeros(3 * n_vox)), f64(np.zeros(3 * n_vox)),
                   f64(np.zeros(ck.LINK_LOADS * n_links))),
        ck.Output(ctl, f64(COLLIDE_MARGIN * batch.fparams[:, F_L]),
                  f64(np.zeros(3 * int(froff[-1]))), f64(np.zeros(R * ck.COM_ROWS * 4))),
    )


def run_batch(robots: list, dev, precision: str = "float64", chunk: int | None = None,
              memory: str = "auto") -> BatchOutput:
    """Run the built robots (``sim.system.Robot``) to the end on CUDA device ``dev``, their
    links in ``precision`` (``sim.models.PRECISIONS``). ``memory``: "auto" (each robot in
    shared memory if it fits, else global) or "global" (every robot on the global arrays,
    for tests of that path)."""
    cuda = cuda_module()
    from . import cuda_kernels as ck

    if precision not in PRECISIONS:
        raise EngineUnavailable(f"precision: must be one of {', '.join(PRECISIONS)} (got {precision!r})")
    batch, state = pack(robots)
    R = len(robots)
    host = kernel_inputs(batch, state)
    args = tuple(type(group)(*(cuda.to_device(x) for x in group)) for group in host)
    body, out = args[5], args[7]
    counts, links = np.diff(batch.voff), np.diff(batch.loff)
    n_frames = batch.iparams[:, I_N_FRAMES].astype(np.int64)
    froff = host[0].froff.astype(np.int64)

    threads = threads_per_block()
    sim_mode = simulator()
    scratch = 8 * (threads + ck.SCRATCH_WORDS)  # every block's reductions and flags
    need = np.array([shared_bytes(int(n), int(m)) for n, m in zip(counts, links, strict=True)])
    need = need + scratch
    in_shared = ck.rollout_kernel(True, threads, precision)
    in_global = ck.rollout_kernel(False, threads, precision)
    total = int(batch.iparams[:, I_STEPS].max(initial=0)) + 1
    chunk = total if sim_mode else max(1, int(chunk or CHUNK_STEPS))

    # bytes a block may take: anything on the simulator; on a GPU the default, or more once
    # the kernel has opted in (``_shared_limit``, after its first compilation)
    limit = need.max() if sim_mode else (SHARED_DEFAULT if need.max() <= SHARED_DEFAULT else None)
    switch = sys.getswitchinterval()
    if sim_mode:  # the simulator's threads meet at every sync: hand the GIL over often
        sys.setswitchinterval(SIMULATOR_SWITCH_SECONDS)
    started = time.perf_counter()
    try:
        for _ in range(-(-total // chunk)):  # every robot is done after this many launches
            running = out.ctl.copy_to_host()[:, ck.C_RUNNING] != 0
            if not running.any():
                break
            if limit is None:  # compile once, then let it use more than the default if it may
                first = cuda.to_device(np.flatnonzero(running)[:1].astype(np.int32))
                try:
                    in_shared = in_shared.specialize(np.int32(chunk), first, *args)
                    limit = _shared_limit(in_shared, dev, int(need.max()))
                except Exception:  # no opt-in here: the robots beyond the default run in global memory
                    limit = SHARED_DEFAULT
            fits = need <= limit if memory == "auto" else np.zeros(R, dtype=bool)
            for kernel, mask in ((in_shared, fits & running), (in_global, ~fits & running)):
                which = np.flatnonzero(mask).astype(np.int32)
                if len(which):
                    nbytes = int(need[which].max()) if kernel is in_shared else scratch
                    kernel[len(which), threads, 0, nbytes](np.int32(chunk), cuda.to_device(which), *args)
            cuda.synchronize()
    finally:
        sys.setswitchinterval(switch)
    seconds = time.perf_counter() - started

    ctl = out.ctl.copy_to_host()
    com = out.com.copy_to_host().reshape(R, ck.COM_ROWS, 4)
    status = ctl[:, ck.C_CODE].astype(np.int64)
    done = ctl[:, ck.C_DONE].astype(np.int64)
    com_count = ctl[:, ck.C_NCOM].astype(np.int64)
    if (ctl[:, ck.C_RUNNING] != 0).any():
        raise RuntimeError("cuda engine: robots still running after their step count")
    return BatchOutput(seconds, batch.voff, froff, n_frames, body.pos.copy_to_host().reshape(-1, 3),
                       out.frames.copy_to_host()[: 3 * int(froff[-1])].reshape(-1, 3), com,
                       com_count, status, done)
