"""Recorded motion of one genome: the evaluation run again with frames recorded.

``record_motion`` takes the same JSON task as ``worker.evaluate.evaluate_batch`` (genome,
environment, Young's modulus, cycles, encoding) and returns arrays for replay (the
dashboard, animations). The simulation is deterministic, so the motion is the one that was
evaluated.
"""

from __future__ import annotations

from typing import Any

import numpy as np

MAX_FRAMES = 2000


def record_motion(
    task: dict[str, Any], every: int = 100, max_frames: int = 500, threads: int | None = 1
) -> dict[str, np.ndarray]:
    """Simulate ``task`` recording voxel positions every ``every`` steps, then keep at most
    ``max_frames`` frames evenly spread (the first and last kept).

    Returns:
        t: (F,) float64 seconds of simulated time.
        voxels: (V, 3) int64 lattice indices (i, j, k) of the simulated voxels.
        material: (V,) int64, 1 passive, 2 active.
        positions: (F, V, 3) float64 voxel centres, metres.
        dt: () float64 time step, seconds; stable: () bool.
    Raises ValueError for a genome with an empty body.
    """
    from softevo.worker.evaluate import _express  # the one genome -> scene path of the workers

    from softevo import sim

    phenotype, scene = _express(task)
    scene["record"] = {"every": int(every)}
    result = sim.simulate_many([scene], threads=threads)[0]
    t = np.asarray(result.frames["t"], dtype=float)
    positions = np.asarray(result.frames["positions"], dtype=float)
    keep = min(len(t), max(1, min(int(max_frames), MAX_FRAMES)))
    index = np.unique(np.linspace(0, len(t) - 1, keep).round().astype(int))
    voxels = np.asarray(result.voxels, dtype=np.int64).reshape(-1, 3)
    material = np.asarray(phenotype.body, dtype=np.int64)[tuple(voxels.T)]
    return {
        "t": t[index],
        "voxels": voxels,
        "material": material,
        "positions": positions[index],
        "dt": np.float64(result.dt),
        "stable": np.bool_(result.stable),
    }
