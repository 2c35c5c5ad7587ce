"""Evaluate genomes: JSON tasks in, JSON results out (plain types only).

``evaluate_batch`` is the job function every executor calls (the local process pool here,
an RQ worker by its dotted name ``worker.evaluate.evaluate_batch`` in issue 5). It never
touches SQL or HTTP. Each task:

    {"id": int,                      # the algorithm's id of the individual
     "genome": {...},                # Genotype.to_dict()
     "environment": "land" | "water",
     "youngs_modulus": float,        # Pa
     "cycles": int,
     "workspace": [x, y, z],         # or a full "encoding" (EncodingConfig.to_dict())
     "encoding": {...}}              # optional, wins over "workspace"

Each result: {"id", "distance", "stable", "error", "voxel_count", "active_share",
"frequency", "descriptors": {...} | None, "phenotype": {...} | None, "seconds"}. Anything
that goes wrong with one genome (a bad genome, a scene error, a crash of the simulator)
becomes that result's ``error`` with the worst fitness (distance 0, stable false); the other
genomes of the batch are still evaluated.
"""

from __future__ import annotations

import subprocess
import sys
import time
import traceback
from typing import Any

FAILED_DISTANCE = 0.0


def _encoding(task: dict[str, Any]):
    from softevo.evolution.genotype import EncodingConfig

    if task.get("encoding"):
        return EncodingConfig.from_dict(task["encoding"])
    return EncodingConfig(workspace=tuple(int(n) for n in task["workspace"]))


def _express(task: dict[str, Any]):
    """(phenotype, scene) of a task; raises on a bad genome."""
    from softevo.evolution.genotype import Genotype, develop

    phenotype = develop(Genotype.from_dict(task["genome"]), _encoding(task))
    if phenotype.voxel_count == 0:
        raise ValueError("empty body")
    scene = phenotype.to_scene(task["environment"], task["youngs_modulus"], task["cycles"])
    return phenotype, scene


def _failure(task: dict[str, Any], error: str, phenotype=None) -> dict[str, Any]:
    result = {"id": task["id"], "distance": FAILED_DISTANCE, "stable": False, "error": error}
    result.update(_phenotype_fields(phenotype))
    result["seconds"] = 0.0
    return result


def crashed(task: dict[str, Any], error: str) -> dict[str, Any]:
    """The result of a task whose evaluation could not finish (e.g. its process died)."""
    return _failure(task, error)


def _phenotype_fields(phenotype) -> dict[str, Any]:
    if phenotype is None:
        return {
            "voxel_count": 0,
            "active_share": 0.0,
            "frequency": None,
            "descriptors": None,
            "phenotype": None,
        }
    return {
        "voxel_count": int(phenotype.voxel_count),
        "active_share": float(phenotype.active_share),
        "frequency": float(phenotype.frequency),
        "descriptors": _descriptors(phenotype),
        "phenotype": _plain(phenotype.summary()),
    }


def _descriptors(phenotype) -> dict[str, float] | None:
    """Shape descriptors (symmetry, branching, shape_entropy, ...) or None if unavailable."""
    try:
        from softevo.evolution.descriptors import describe_phenotype

        return _plain(describe_phenotype(phenotype))
    except Exception as exc:  # descriptors never fail an evaluation
        return {"error": f"{type(exc).__name__}: {exc}"}


def _plain(value: Any) -> Any:
    """Numpy scalars and arrays to plain JSON types (RQ's JSON serialiser needs them)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def _simulate(scenes: list[dict], threads: int | None) -> list[Any]:
    """Results of all scenes in one call; one by one (errors isolated) if the batch fails."""
    from softevo import sim

    try:
        return sim.simulate_many(scenes, threads=threads)
    except Exception:
        results = []
        for scene in scenes:
            try:
                results.append(sim.simulate_many([scene], threads=threads)[0])
            except Exception as exc:
                results.append(exc)
        return results


def _result(task: dict[str, Any], phenotype, outcome: Any, seconds: float) -> dict[str, Any]:
    if isinstance(outcome, BaseException):
        return _failure(task, f"{type(outcome).__name__}: {outcome}", phenotype)
    distance = float(outcome.distance)
    stable = bool(outcome.stable) and distance == distance  # NaN is unstable
    error = None if stable else (outcome.reason or "unstable")
    result = {
        "id": task["id"],
        "distance": distance if stable else FAILED_DISTANCE,
        "stable": stable,
        "error": error,
    }
    result.update(_phenotype_fields(phenotype))
    result["seconds"] = seconds
    return result


def evaluate_batch(tasks: list[dict[str, Any]], threads: int | None = None) -> list[dict[str, Any]]:
    """Evaluate ``tasks`` (see the module doc); results in the same order, plain JSON types.

    All robots of the batch run in one ``sim.simulate_many`` call (``threads``: numba threads
    for it; None keeps the process's setting).
    """
    results: list[dict[str, Any] | None] = [None] * len(tasks)
    runnable: list[tuple[int, Any, dict]] = []
    for k, task in enumerate(tasks):
        phenotype = None
        try:
            phenotype, scene = _express(task)
            runnable.append((k, phenotype, scene))
        except Exception as exc:
            message = str(exc) if str(exc) == "empty body" else f"{type(exc).__name__}: {exc}"
            results[k] = _failure(task, message, phenotype)
    if runnable:
        start = time.perf_counter()
        outcomes = _simulate([scene for _, _, scene in runnable], threads)
        seconds = (time.perf_counter() - start) / len(runnable)
        for (k, phenotype, _), outcome in zip(runnable, outcomes, strict=True):
            try:
                results[k] = _result(tasks[k], phenotype, outcome, seconds)
            except Exception as exc:
                results[k] = _failure(tasks[k], f"{type(exc).__name__}: {exc}")
    return results  # type: ignore[return-value]


def warm_up(threads: int | None = 1) -> None:
    """Compile (or load from numba's cache) the simulator once in this process."""
    from softevo import sim

    body = [[[2]], [[1]]]
    sim.simulate_many([{"body": body, "duration": {"cycles": 1}}], threads=threads)


_CACHE_READY = False


def ensure_compiled() -> None:
    """Fill numba's on-disk cache from a short subprocess, once per process, before this
    process runs the simulator.

    On a cold cache the kernels are then compiled once, not by every pool process at the
    same time, and every process (a resumed run's included) runs the same cached machine
    code. (A kernel compiled fresh once rounded differently from the cached one; the
    simulator has since dropped the fastmath flags that allowed it, and this stays as a
    guard.)
    """
    global _CACHE_READY
    if _CACHE_READY:
        return
    code = "from softevo.worker.evaluate import warm_up; warm_up()"
    subprocess.run([sys.executable, "-c", code], check=False, capture_output=True)
    _CACHE_READY = True


def init_pool_process() -> None:
    """Process-pool initializer: ignore Ctrl-C, one numba thread per process (the pool is the
    parallelism), then warm the simulator so the first real batch pays no compilation."""
    import signal

    import numba

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the coordinator's to handle
    numba.set_num_threads(1)
    try:
        warm_up(threads=1)
    except Exception:  # a broken simulator shows up in the results, with its error
        traceback.print_exc()
