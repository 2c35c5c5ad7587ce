"""The Warp engine: ``simulate_many`` for a GPU (or Warp's CPU device), same scenes, same
``Result`` as ``sim.engine``.

Scenes go through the one scene -> arrays path (``parse_scene``, ``build_robot``, ``pack``);
the packed batch is copied to the device once, with voxel and link indices made global, and
``sim.warp_kernels`` steps every robot of it at once: per step one launch over all links,
two over all voxels and one over all robots. A robot that has run its steps or diverged is
masked, not re-packed. The launches of ``chunk`` steps are captured once (``wp.ScopedCapture``:
a CUDA graph on a GPU, Warp's recorded launch stream replayed in C++ on the CPU device) and
replayed until every robot is done; between chunks the host only asks whether any still runs.

Precision: float64 (default) agrees with the numba engine to rounding; float32 halves the
memory traffic (docs/gpu.md says when it may be used). Warp is imported on first use only;
without it, or without the device asked for, ``EngineUnavailable`` says so in one line.
"""

from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager
from types import SimpleNamespace
from typing import Any

import numpy as np

from .engine import Result, _result, prepare
from .engines import PRECISIONS, EngineUnavailable
from .kernels import COLLIDE_MARGIN, LINK_OUT_ROWS, LINK_STATE_ROWS
from .scene import Scene
from .scene import ModelOptions
from .system import COM_SAMPLES, F_L, I_N_FRAMES, I_STEPS, pack

DEFAULT_DEVICE = "cuda:0"
# Steps per captured chunk: on a GPU long graphs amortise the launch of each; on the CPU
# device replay costs little per launch but recording one costs ~0.5 ms, so short ones.
CHUNK_STEPS = {"cuda": 500, "cpu": 25}


def warp_module():
    """The ``warp`` module, initialised quietly; ``EngineUnavailable`` if it is missing."""
    try:
        import warp as wp
    except ImportError:
        raise EngineUnavailable(
            "the warp engine needs the warp-lang package: pip install 'softevo[gpu]'"
        ) from None
    wp.config.log_level = wp.LOG_WARNING  # no banner, no line per module load
    with _native_stderr_silenced():  # the CUDA driver's absence is ours to report
        wp.init()  # once per process (later calls return at once)
    return wp


@contextmanager
def _native_stderr_silenced():
    """File descriptor 2 points at /dev/null inside (Warp's native code prints the missing
    CUDA driver there on every machine without a GPU; ``device_of`` says it in one line)."""
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def device_of(name: str | None):
    """The Warp device called ``name`` (default ``DEFAULT_DEVICE``); ``EngineUnavailable``
    naming the devices there are if it does not exist here."""
    wp = warp_module()
    name = name or DEFAULT_DEVICE
    available = ", ".join(str(d) for d in wp.get_devices())
    try:
        device = wp.get_device(name)
    except (ValueError, RuntimeError, KeyError, TypeError):
        device = None
    if device is None:
        hint = " (use --device cpu for Warp's CPU device)" if name.startswith("cuda") else ""
        raise EngineUnavailable(f"device: no Warp device {name!r} here; there are: {available}{hint}")
    return device


def simulate_many(
    scenes: list[dict | Scene],
    device: str | None = None,
    precision: str = "float64",
    chunk: int | None = None,
) -> list[Result]:
    """Simulate many robots in one batch on a Warp device; results in the order of
    ``scenes``. ``precision``: "float64" or "float32"; ``chunk``: steps per captured graph
    (default ``CHUNK_STEPS`` for the kind of device)."""
    if precision not in PRECISIONS:
        raise EngineUnavailable(f"precision: must be one of {', '.join(PRECISIONS)} (got {precision!r})")
    dev = device_of(device)
    parsed, robots, results, runnable = prepare(scenes)
    for scene in parsed:
        if scene.options != ModelOptions():
            raise EngineUnavailable(
                f"the warp engine runs only the voxelyze-2 model with its default options "
                f"(got model {scene.model}); use the numba engine for this scene")
    if runnable:
        sub = [robots[k] for k in runnable]
        out = run_batch(sub, dev, precision, chunk)
        for r, k in enumerate(runnable):
            results[k] = _result(parsed[k], robots[k], 0, *out.robot(r))
    return results  # type: ignore[return-value]


class BatchOutput:
    """What a run leaves on the host, cut per robot in ``robot(r)`` as ``sim.engine._result``
    takes it (a one-robot batch), and the seconds its step loop took."""

    def __init__(self, seconds, voff, foff, n_frames, pos, frames, com_traj, com_count, status, done):
        self.seconds = seconds  # wall time of the step loop alone (after capture)
        self.voff, self.foff, self.n_frames = voff, foff, n_frames
        self.pos, self.frames, self.com_traj = pos, frames, com_traj
        self.com_count, self.status, self.done = com_count, status, done

    @property
    def voxel_steps(self) -> float:
        """Voxel-steps the run stepped: each robot's steps times its voxels."""
        return float(np.sum(self.done * np.diff(self.voff)))

    def robot(self, r: int) -> tuple[Any, ...]:
        v0, v1 = self.voff[r], self.voff[r + 1]
        n = v1 - v0
        f0, nf = self.foff[r], self.n_frames[r]
        frames = self.frames[f0 : f0 + nf * n].reshape(nf, n, 3)
        return (
            SimpleNamespace(voff=np.array([0, n])),
            SimpleNamespace(pos=self.pos[v0:v1]),
            frames,
            self.com_traj[r : r + 1],
            self.com_count[r : r + 1],
            self.status[r : r + 1],
            self.done[r : r + 1],
        )


def _offsets(counts) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)


def run_batch(robots: list, dev, precision: str = "float64", chunk: int | None = None) -> BatchOutput:
    """Run the built robots (``sim.system.Robot``) to the end on Warp device ``dev``."""
    wp = warp_module()
    from .warp_kernels import MAX_CANDIDATES, build

    kern = build(precision)
    real = np.float64 if precision == "float64" else np.float32
    batch, state = pack(robots)
    n_robots = len(robots)
    voff, loff, soff = batch.voff, batch.loff, batch.soff
    n_vox, n_links = int(voff[-1]), int(loff[-1])
    robot_of_voxel = np.repeat(np.arange(n_robots), np.diff(voff))
    robot_of_link = np.repeat(np.arange(n_robots), np.diff(loff))
    robot_of_surface = np.repeat(np.arange(n_robots), np.diff(soff))

    def globalise(local, offsets, owner):
        local = np.asarray(local)
        shift = offsets[owner].reshape((-1,) + (1,) * (local.ndim - 1))
        return np.where(local >= 0, local + shift, -1)

    def no_link_as_minus_one(vlink, loff, owner):
        """``Robot.vlink`` marks a face without a link by the robot's link count (the numba
        kernels read a zero there); the Warp kernels test for -1."""
        count = np.diff(loff)[owner][:, None]
        return np.where(vlink == count, -1, vlink)

    n_frames = batch.iparams[:, I_N_FRAMES].astype(np.int64)
    foff = _offsets(n_frames * np.diff(voff))
    if foff[-1] >= 2**31 or n_vox * MAX_CANDIDATES >= 2**31:  # Warp indexes with int32
        raise EngineUnavailable(
            f"batch too large for one Warp launch ({n_vox} voxels, {int(foff[-1])} frame rows): "
            "split it or record fewer frames"
        )
    surface = globalise(batch.surface, voff, robot_of_surface)
    is_surface = np.zeros(n_vox, dtype=np.int32)
    is_surface[surface] = 1

    def dev_array(a, dtype):
        return wp.array(np.ascontiguousarray(a, dtype=dtype), device=dev)

    def i32(a):
        return dev_array(a, np.int32)

    def fl(a):
        return dev_array(a, real)

    a = SimpleNamespace(
        running=i32(np.ones(n_robots)),
        step=i32(np.zeros(n_robots)),
        robot=i32(robot_of_voxel),
        link_robot=i32(robot_of_link),
        fp=fl(batch.fparams),
        ip=i32(batch.iparams),
        voff=i32(voff),
        foff=i32(foff),
        soff=i32(soff),
        flags=i32(batch.flags),
        cos_phase=fl(batch.cos_phase),
        sin_phase=fl(batch.sin_phase),
        phase=fl(batch.phase),
        vc=fl(batch.vconst),
        ext_force=fl(batch.ext_force),
        nbr=i32(globalise(batch.nbr, voff, robot_of_voxel)),
        vlink=i32(globalise(no_link_as_minus_one(batch.vlink, loff, robot_of_voxel), loff, robot_of_voxel)),
        surface=i32(surface),
        is_surface=i32(is_surface),
        link_neg=i32(globalise(batch.link_neg, voff, robot_of_link)),
        link_pos=i32(globalise(batch.link_pos, voff, robot_of_link)),
        link_axis=i32(batch.link_axis),
        link_stiff=fl(batch.link_stiff),
        link_damp=fl(batch.link_damp),
        pos=fl(state.pos),
        quat=fl(state.quat),
        lin_mom=fl(state.lin_mom),
        ang_mom=fl(state.ang_mom),
        size=fl(np.zeros(n_vox)),
        force=fl(np.zeros((n_vox, 3))),
        moment=fl(np.zeros((n_vox, 3))),
        static=i32(np.ones(n_vox)),
        contact=i32(np.zeros(n_vox)),
        cand=i32(np.zeros((n_vox, MAX_CANDIDATES))),
        ncand=i32(np.zeros(n_vox)),
        link_state=fl(np.zeros((max(n_links, 1), LINK_STATE_ROWS))),
        link_out=fl(np.zeros((max(n_links, 1), LINK_OUT_ROWS))),
        bad=i32(np.zeros(n_robots)),
        nonfinite=i32(np.zeros(n_robots)),
        speed2=fl(np.zeros(n_robots)),
        travel=fl(COLLIDE_MARGIN * batch.fparams[:, F_L]),
        status=i32(np.zeros(n_robots)),
        done=i32(np.zeros(n_robots)),
        n_com=i32(np.zeros(n_robots)),
        com_traj=fl(np.zeros((n_robots, COM_SAMPLES + 3, 4))),
        frames=fl(np.zeros((max(int(foff[-1]), 1), 3))),
    )
    voxel_args = [a.running, a.robot, a.step, a.fp, a.ip, a.flags, a.cos_phase, a.sin_phase, a.phase, a.vc]
    step_launches = [
        (
            kern.links,
            n_links,
            [
                a.running,
                a.link_robot,
                a.fp,
                a.link_neg,
                a.link_pos,
                a.link_axis,
                a.link_stiff,
                a.link_damp,
                a.pos,
                a.quat,
                a.size,
                a.link_state,
                a.link_out,
                a.bad,
            ],
        ),
        (
            kern.forces,
            n_vox,
            [
                a.running,
                a.robot,
                a.fp,
                a.ip,
                a.flags,
                a.vc,
                a.ext_force,
                a.nbr,
                a.vlink,
                a.surface,
                a.soff,
                a.is_surface,
                a.travel,
                a.cand,
                a.ncand,
                a.link_out,
                a.pos,
                a.quat,
                a.lin_mom,
                a.ang_mom,
                a.size,
                a.force,
                a.moment,
                a.static,
                a.contact,
            ],
        ),
        (
            kern.integrate,
            n_vox,
            voxel_args
            + [
                a.force,
                a.moment,
                a.static,
                a.contact,
                a.pos,
                a.quat,
                a.lin_mom,
                a.ang_mom,
                a.size,
                a.speed2,
                a.nonfinite,
            ],
        ),
        (
            kern.robots,
            n_robots,
            robot_args := [
                1,
                a.running,
                a.step,
                a.fp,
                a.ip,
                a.voff,
                a.foff,
                a.vc,
                a.pos,
                a.bad,
                a.nonfinite,
                a.speed2,
                a.travel,
                a.status,
                a.done,
                a.n_com,
                a.com_traj,
                a.frames,
            ],
        ),
    ]
    step_launches = [s for s in step_launches if s[1] > 0]
    wp.launch(kern.actuate, dim=n_vox, inputs=voxel_args + [a.size], device=dev)
    wp.launch(kern.robots, dim=n_robots, inputs=[0] + robot_args[1:], device=dev)
    total = int(batch.iparams[:, I_STEPS].max())
    chunk = max(1, min(chunk or CHUNK_STEPS["cuda" if dev.is_cuda else "cpu"], total))
    with wp.ScopedCapture(device=dev) as capture:  # a CUDA graph, or Warp's CPU replay
        for _ in range(chunk):
            for kernel, dim, inputs in step_launches:
                wp.launch(kernel, dim=dim, inputs=inputs, device=dev)
    wp.synchronize_device(dev)
    started = time.perf_counter()
    done_steps = 0
    while done_steps < total and a.running.numpy().any():
        wp.capture_launch(capture.graph)
        done_steps += chunk
    wp.synchronize_device(dev)
    seconds = time.perf_counter() - started
    return BatchOutput(
        seconds,
        voff,
        foff,
        n_frames,
        a.pos.numpy().astype(np.float64),
        a.frames.numpy().astype(np.float64),
        a.com_traj.numpy().astype(np.float64),
        a.n_com.numpy().astype(np.int64),
        a.status.numpy().astype(np.int64),
        a.done.numpy().astype(np.int64),
    )
