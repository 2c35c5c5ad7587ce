"""What an evaluation returns, and how the engines make it: ``Result`` (docs/spec.md
section 1), read from a run's arrays by ``from_run``, or ``unrun`` for a robot refused before
it runs; ``prepare`` parses and builds a batch of scenes for any engine and refuses those
past their step budget. Every engine (``sim.engines``) returns these; none imports another.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import worlds
from .physics import MAX_STRAIN
from .scene import Scene, parse_scene
from .system import (
    F_DT,
    F_L,
    I_RECORD,
    I_STEPS,
    MAX_CONTACTS,
    MIN_RESOLVED_STEPS_PER_CYCLE,
    STATUS_CONTACTS,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_STRAIN,
    Robot,
    build_robot,
    steps_per_cycle,
)


@dataclass
class Result:
    """What one evaluation returns (docs/spec.md section 1). Distances in voxel lengths."""

    stable: bool
    reason: str | None
    dt: float  # seconds
    steps: int
    simulated_seconds: float
    voxels: np.ndarray  # (n, 3) int lattice indices of the simulated voxels
    final_positions: np.ndarray  # (n, 3) metres
    com_start: np.ndarray  # (3,) metres, after settling
    com_end: np.ndarray  # (3,) metres
    displacement: np.ndarray  # (3,) metres
    distance: float  # voxel lengths: horizontal on land (voxelyze-2), 3-D otherwise; 0 when unstable
    com_trajectory: dict = field(default_factory=dict)  # {"t": (k,), "com": (k, 3)}
    frames: dict | None = None  # {"t": (f,), "positions": (f, n, 3)} when recorded
    removed_voxels: int = 0  # voxels dropped as not face-connected to the largest component

    def __repr__(self) -> str:
        """The scalars and the arrays' sizes, not their contents (a trajectory is thousands
        of numbers)."""
        frames = None if self.frames is None else len(self.frames.get("t", ()))
        samples = len(self.com_trajectory.get("t", ()))
        return (
            f"Result(distance={self.distance:.6g}, stable={self.stable}, reason={self.reason!r}, "
            f"steps={self.steps}, dt={self.dt:.3g}, simulated_seconds={self.simulated_seconds:.4g}, "
            f"voxels={len(self.voxels)}, removed_voxels={self.removed_voxels}, "
            f"com_trajectory=<{samples} samples>, frames={'None' if frames is None else f'<{frames}>'})"
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types only (lists, floats, ints, bools, None)."""
        out = {
            "stable": bool(self.stable),
            "reason": self.reason,
            "dt": float(self.dt),
            "steps": int(self.steps),
            "simulated_seconds": float(self.simulated_seconds),
            "voxels": np.asarray(self.voxels).astype(int).tolist(),
            "final_positions": np.asarray(self.final_positions, float).tolist(),
            "com_start": np.asarray(self.com_start, float).tolist(),
            "com_end": np.asarray(self.com_end, float).tolist(),
            "displacement": np.asarray(self.displacement, float).tolist(),
            "distance": float(self.distance),
            "removed_voxels": int(self.removed_voxels),
            "com_trajectory": {k: np.asarray(v, float).tolist()
                               for k, v in self.com_trajectory.items()},
        }
        if self.frames is not None:
            out["frames"] = {k: np.asarray(v, float).tolist() for k, v in self.frames.items()}
        return out


def _budget_reason(scene: Scene, robot: Robot) -> str | None:
    per_cycle = steps_per_cycle(robot)
    if per_cycle < MIN_RESOLVED_STEPS_PER_CYCLE:
        return (f"actuation too fast to resolve: {per_cycle:.3g} steps per cycle (dt "
                f"{robot.fparams[F_DT]:.3g} s), fewer than {MIN_RESOLVED_STEPS_PER_CYCLE}")
    steps = int(robot.iparams[I_STEPS])
    if steps > scene.max_steps:
        return (f"step budget exceeded: needs {steps} steps (dt {robot.fparams[F_DT]:.3g} s), "
                f"more than max_steps {scene.max_steps}")
    return None


def from_run(scene: Scene, robot: Robot, r: int, batch, state, frames, com_traj, com_count,
             status, steps_done) -> Result:
    """Robot r's ``Result`` from the arrays of the run of its batch (``kernels.run_batch``'s
    or the cuda engine's, cut to one robot)."""
    v0, v1 = batch.voff[r], batch.voff[r + 1]
    dt = float(robot.fparams[F_DT])
    L = float(robot.fparams[F_L])
    traj = com_traj[r, : com_count[r]]
    com_start, com_end = traj[0, 1:].copy(), traj[-1, 1:].copy()
    disp = com_end - com_start
    stable = status[r] == STATUS_OK and np.all(np.isfinite(disp))
    reason = None
    if status[r] == STATUS_STRAIN:
        reason = f"diverged: a link's axial strain exceeded {MAX_STRAIN:g} at step {steps_done[r]}"
    elif status[r] == STATUS_CONTACTS:
        reason = (f"self-contact: a voxel had more than {MAX_CONTACTS} contact candidates at step "
                  f"{steps_done[r]} (the engines keep at most {MAX_CONTACTS}; the body had "
                  f"collapsed onto itself)")
    elif status[r] == STATUS_NONFINITE or not stable:
        reason = f"diverged: a voxel's state became non-finite or exploded at step {steps_done[r]}"
    horizontal = worlds.get(scene.environment.kind).floor and scene.options.distance == "horizontal"
    distance = float(np.hypot(disp[0], disp[1]) if horizontal else np.linalg.norm(disp)) / L
    recorded = None
    every = int(robot.iparams[I_RECORD])
    if every > 0:
        n_frames = int(steps_done[r]) // every + 1
        recorded = {"t": np.arange(n_frames) * every * dt,
                    "positions": frames[:n_frames, v0:v1].copy()}
    return Result(
        stable=bool(stable),
        reason=reason,
        dt=dt,
        steps=int(steps_done[r]),
        simulated_seconds=float(steps_done[r]) * dt,
        voxels=robot.voxels,
        final_positions=state.pos[v0:v1].copy(),
        com_start=com_start,
        com_end=com_end,
        displacement=disp,
        distance=distance if stable else 0.0,
        com_trajectory={"t": traj[:, 0].copy(), "com": traj[:, 1:].copy()},
        frames=recorded,
        removed_voxels=robot.removed,
    )


def unrun(robot: Robot, reason: str) -> Result:
    """The ``Result`` of a robot refused before it runs: not stable, ``reason``, no steps."""
    com0 = robot.pos.mean(axis=0)
    return Result(False, reason, float(robot.fparams[F_DT]), 0, 0.0, robot.voxels,
                  robot.pos.copy(), com0, com0.copy(), np.zeros(3), 0.0,
                  {"t": np.zeros(1), "com": com0[None]}, None, robot.removed)


def prepare(scenes: list[dict | Scene]) -> tuple[list[Scene], list[Robot], list[Result | None], list[int]]:
    """Every scene parsed and built, for either engine: (scenes, robots, results, runnable).
    A scene past its step budget has its unrun ``Result`` already; ``runnable`` lists the
    indices still to simulate."""
    parsed = [parse_scene(s) for s in scenes]
    robots = [build_robot(s) for s in parsed]
    results: list[Result | None] = [None] * len(parsed)
    runnable = []
    for k, (scene, robot) in enumerate(zip(parsed, robots, strict=True)):
        reason = _budget_reason(scene, robot)
        if reason:
            results[k] = unrun(robot, reason)
        else:
            runnable.append(k)
    return parsed, robots, results, runnable


