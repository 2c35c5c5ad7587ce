"""Which engine runs a batch: the numba one (default, CPU), the cuda one (NVIDIA GPUs through
numba-cuda, or its simulator) or the sleep one (no physics, only the time:
``sim.sleep_engine``, for benches of the system around the simulator), and the one error an
unusable engine raises.

The engines take the same scenes and return the same ``Result`` (``sim.engine``); the cuda
engine lives in ``sim.cuda_engine`` and imports numba-cuda only when it is asked for.
"""

from __future__ import annotations

ENGINES = ("numba", "cuda", "sleep")
PRECISIONS = ("float64", "float32")


class EngineUnavailable(RuntimeError):
    """The engine asked for cannot run here: an unknown engine name, numba-cuda not
    installed, or no such device. The message is one line meant for a person (the CLI prints it, exit 2)."""


def check_engine(engine: str) -> str:
    """``engine`` if it is one of ``ENGINES``; else ``EngineUnavailable``."""
    if engine not in ENGINES:
        raise EngineUnavailable(f"engine: must be one of {', '.join(ENGINES)} (got {engine!r})")
    return engine
