"""The numba engine (the default, CPU): a batch of robots in one compiled call, one robot
per parallel task (``sim.kernels.run_batch``).

``simulate_many(scenes, threads, device)`` takes scene dicts (docs/spec.md section 1) or
parsed ``Scene`` objects and returns a ``Result`` (``sim.result``) per scene, in order; an
unstable robot yields ``stable=False`` with a reason, never an exception. Invalid scenes
raise ``SceneError`` before anything runs. Pick an engine by name with ``sim.engines``.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np

from . import kernels
from .cache import drop_foreign_entries, drop_stale_entries
from .engines import EngineUnavailable
from .result import Result, from_run, prepare
from .scene import Scene
from .system import COM_SAMPLES, I_N_FRAMES, I_STEPS, pack

_HERE = Path(kernels.__file__).parent
# the sources whose constants and inlined functions the cached kernels hold
KERNEL_SOURCES = [_HERE / name for name in ("kernels.py", "physics.py", "substeps.py",
                                                  "system.py")]
drop_foreign_entries(_HERE / "__pycache__")
drop_stale_entries(_HERE / "__pycache__", KERNEL_SOURCES)

# each precision's link dtype, as the empty array ``kernels.run_batch`` takes it (``real``)
REALS = {"float64": np.zeros(0, np.float64), "mixed": np.zeros(0, np.float32)}


def simulate_many(scenes: list[dict | Scene], threads: int | None = None,
                  device: str | None = None) -> list[Result]:
    """Simulate many robots in one compiled call, one robot per parallel task.

    ``threads`` caps numba's threads for this call (default: all cores numba was given).
    ``device``: None or "cpu" (the numba engine runs on this machine's CPU). Results come
    back in the order of ``scenes``.
    """
    if device not in (None, "", "cpu"):
        raise EngineUnavailable(f"device: the numba engine runs on the cpu (got {device!r})")
    parsed, robots, results, runnable = prepare(scenes)
    groups: dict[str, list[int]] = {}
    for k in runnable:  # one compiled call per precision (``kernels.run_batch``'s ``real``)
        groups.setdefault(parsed[k].options.precision, []).append(k)
    previous = numba.get_num_threads()
    if threads is not None:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    try:
        for precision, members in groups.items():
            for r, result in zip(members, _run(parsed, robots, members, REALS[precision]),
                                 strict=True):
                results[r] = result
    finally:
        numba.set_num_threads(previous)
    return results  # type: ignore[return-value]


def _run(parsed: list[Scene], robots: list, members: list[int], real: np.ndarray) -> list[Result]:
    """The results of robots ``members`` (indices into ``parsed`` / ``robots``), run in one
    compiled call with their links in ``real``'s dtype."""
    # longest robots first, so the parallel tasks finish together
    order = sorted(members, key=lambda k: -robots[k].iparams[I_STEPS] * len(robots[k].pos))
    sub = [robots[k] for k in order]
    batch, state = pack(sub)
    n = int(batch.voff[-1])
    n_frames = max(int(r.iparams[I_N_FRAMES]) for r in sub)
    frames = np.zeros((n_frames, n if n_frames else 0, 3))
    com_traj = np.zeros((len(sub), COM_SAMPLES + 3, 4))
    com_count = np.zeros(len(sub), dtype=np.int64)
    status = np.zeros(len(sub), dtype=np.int64)
    steps_done = np.zeros(len(sub), dtype=np.int64)
    kernels.run_batch(batch, state, frames, com_traj, com_count, status, steps_done, real)
    out = {k: from_run(parsed[k], robots[k], r, batch, state, frames, com_traj, com_count,
                       status, steps_done) for r, k in enumerate(order)}
    return [out[k] for k in members]
