"""Evaluate genomes: the job function every executor calls, and the simulator's warm-up.

``evaluate_batch`` takes a list of JSON tasks and returns their JSON results in order
(``worker.tasks`` defines both formats). The local process pool calls it directly, an RQ
worker by its dotted name ``softevo.worker.evaluate.evaluate_batch``. It never touches SQL
or HTTP. Anything that goes wrong with one genome (a bad genome, a scene error, a crash of
the simulator) becomes that result's ``error`` with the worst fitness
(``worker.tasks.failed``); the other genomes of the batch are still evaluated.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
import traceback
from collections.abc import Callable
from typing import Any

import numpy as np

from softevo.evolution.outcome import Outcome
from softevo.worker.tasks import EmptyBody, Task, TaskResult, failed, generation_tasks, scenes_of

ENGINE_ENV, DEVICE_ENV = "SOFTEVO_ENGINE", "SOFTEVO_DEVICE"


def engine_options() -> dict[str, Any]:
    """The engine this process evaluates on, as keyword arguments of ``sim.simulate_many``:
    ``$SOFTEVO_ENGINE`` (``numba``, the default, ``cuda`` or ``sleep``) and ``$SOFTEVO_DEVICE``
    (the CUDA device, e.g. ``cuda:0``, or the sleep engine's ``x<factor>``). Empty for the
    default engine: ``simulate_many`` is then called with its own defaults."""
    engine = os.environ.get(ENGINE_ENV) or "numba"
    if engine == "numba":
        return {}
    options: dict[str, Any] = {"engine": engine}
    if os.environ.get(DEVICE_ENV):
        options["device"] = os.environ[DEVICE_ENV]
    return options


Simulate = Callable[[list[dict[str, Any]]], list[Outcome]]
"""A function over scenes giving one scored ``Outcome`` per scene, in order (``simulate``)."""


def simulate(scenes: list[dict], threads: int | None = None) -> list[Outcome]:
    """The scored outcomes of all scenes from one ``sim.simulate_many`` call on this
    process's engine; one by one (each failure its own) if the batch fails."""
    from softevo import sim
    from softevo.sim.engines import EngineUnavailable

    options = engine_options()
    try:
        return [Outcome.of_result(result) for result in sim.simulate_many(scenes, threads=threads, **options)]
    except EngineUnavailable:
        raise  # this process cannot evaluate at all: no per-genome retry
    except Exception:
        outcomes = []
        for scene in scenes:
            try:
                (result,) = sim.simulate_many([scene], threads=threads, **options)
                outcomes.append(Outcome.of_result(result))
            except Exception as exc:
                outcomes.append(Outcome.crash(exc))
        return outcomes


def evaluate_batch(tasks: list[dict[str, Any]], threads: int | None = None,
                   simulator: Simulate | None = None) -> list[dict[str, Any]]:
    """Evaluate JSON ``tasks`` (``Task.to_json``); JSON results (``TaskResult.to_json``) in the
    same order.

    All robots of the batch run in one call of ``simulator`` (default ``simulate``, the
    engine's ``sim.simulate_many``; a test may give a stand-in over scenes); ``threads``:
    numba threads for it (None keeps the process's setting). A compound world's parts are
    combined by ``Outcome.combine``. On the sleep engine the results carry no shape
    descriptors: its workers stand in for the cluster's in benches and spend no CPU.
    """
    describe = engine_options().get("engine") != "sleep"
    results: list[TaskResult | None] = [None] * len(tasks)
    runnable: list[tuple[int, Task, Any, list[dict]]] = []
    for k, data in enumerate(tasks):
        phenotype = None
        try:
            task = Task.from_json(data)
            # a compound world: one scene per part; the phenotype's arrays, not lists
            phenotype, scenes = scenes_of(task, arrays=True)
            runnable.append((k, task, phenotype, scenes))
        except EmptyBody as exc:
            results[k] = failed(data, str(exc), phenotype)
        except Exception as exc:
            results[k] = failed(data, f"{type(exc).__name__}: {exc}", phenotype)
    if runnable:
        start = time.perf_counter()
        flat = [scene for *_, scenes in runnable for scene in scenes]
        outcomes = simulate(flat, threads) if simulator is None else _outcomes(simulator, flat)
        seconds = (time.perf_counter() - start) / len(runnable)
        offset = 0
        for k, task, phenotype, scenes in runnable:
            parts, offset = outcomes[offset : offset + len(scenes)], offset + len(scenes)
            try:
                results[k] = TaskResult.of(task, Outcome.combine(parts), phenotype, seconds, describe)
            except Exception as exc:
                results[k] = failed(task, f"{type(exc).__name__}: {exc}")
    return [result.to_json() for result in results]  # type: ignore[union-attr]


def _outcomes(simulator: Simulate, scenes: list[dict]) -> list[Outcome]:
    """``simulator``'s outcomes of ``scenes``; each one the crash when it raises."""
    try:
        return list(simulator(scenes))
    except Exception as exc:
        return [Outcome.crash(exc)] * len(scenes)


def evaluate_generation(algorithm, asked, generation: int, threads: int | None = None,
                        simulator: Simulate | None = None) -> dict[int, Outcome]:
    """The outcomes ({id: ``Outcome``}) of one generation's asked individuals of an
    ``evolution.Evolution``, through ``evaluate_batch`` as every executor evaluates them:
    the ``evolution.runner.Evaluate`` of ``softevo.evolve`` (``simulator``: as
    ``evaluate_batch`` takes it)."""
    results = evaluate_batch(generation_tasks(algorithm, asked, generation), threads, simulator)
    return {result["id"]: TaskResult.from_json(result).outcome for result in results}


def warm_up(threads: int | None = 1) -> None:
    """Compile (or load from numba's cache) the simulator once in this process, with the
    host side's kernels: on the numba engine a robot of the paper's model in water builds
    the contact neighbourhoods and the drag mesh too; the shape descriptors are compiled
    unless on the sleep engine (which describes no shapes)."""
    from softevo import sim
    from softevo.sim import worlds

    body = [[[2]], [[1]]]
    options = engine_options()
    scenes = [{"body": body, "duration": {"cycles": 1}}]
    if not options:
        scenes.append({"body": body, "duration": {"cycles": 1}, "model": "voxcad-land-water",
                       "environment": {"kind": worlds.WATER.name}})
    sim.simulate_many(scenes, threads=threads, **options)
    if options.get("engine") != "sleep":
        from softevo.evolution.descriptors import describe

        describe(np.array(body))


_CACHE_READY = False
COMPILING_NOTICE = "compiling the simulator's kernels (first use, about 1-2 min; cached after)"
COMPILING = "compiling"  # what the warm-up subprocess writes to stdout when numba compiles
# The warm-up subprocess: it registers, before anything of softevo is imported (and perhaps
# compiled), a listener of numba's "numba:compile" event, which fires for a compilation and
# never for a kernel loaded from the cache; the first one writes COMPILING to stdout.
WARM_UP_CODE = f"""
from numba.core import event

class FirstCompilation(event.Listener):
    announced = False

    def on_start(self, _event):
        if not self.announced:
            self.announced = True
            print({COMPILING!r}, flush=True)

    def on_end(self, _event):
        pass

event.register("numba:compile", FirstCompilation())
from softevo.worker.evaluate import warm_up
warm_up()
"""


def ensure_compiled() -> None:
    """Fill numba's on-disk cache from a short subprocess, once per process, before this
    process runs the simulator.

    On a cold cache the kernels are then compiled once, not by every pool process at the
    same time, and every process (a resumed run's included) runs the same cached machine
    code, whichever process compiled it. When the subprocess compiles (a cold cache, or
    kernels changed since), ``COMPILING_NOTICE`` goes to stderr, so that a first run does
    not look hung; loading cached kernels says nothing.
    """
    global _CACHE_READY
    if _CACHE_READY:
        return
    process = subprocess.Popen(
        [sys.executable, "-c", WARM_UP_CODE], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    )
    for line in process.stdout:  # type: ignore[union-attr]
        if line.strip() == COMPILING:
            print(COMPILING_NOTICE, file=sys.stderr, flush=True)
    process.wait()
    _CACHE_READY = True


PARENT_POLL_SECONDS = 1.0  # how often a pool process looks whether its parent still lives


def end_with_parent(parent_pid: int, every: float = PARENT_POLL_SECONDS) -> None:
    """End this process (a pool's evaluator) within ``every`` seconds of its parent's death,
    whatever killed the parent (SIGKILL included): a daemon thread watches ``os.getppid()``,
    which changes when the orphan is re-parented. Without it an evaluator of a killed
    ``softevo run`` or ``serve`` waited for work for ever (and Python's resource tracker,
    which ends when they do)."""
    import threading

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(every)
        os._exit(1)

    threading.Thread(target=watch, name="end-with-parent", daemon=True).start()


def init_pool_process(added_worlds: tuple = ()) -> None:
    """Process-pool initializer: end with the parent (``end_with_parent``), register the
    parent's added worlds (``sim.worlds.added``: a spawned process knows only the built-in
    ones), ignore Ctrl-C, one numba thread per process (the pool is the parallelism), then
    warm the simulator so the first real batch pays no compilation."""
    import signal

    import numba

    from softevo.plugins import load_plugins
    from softevo.sim import worlds

    end_with_parent(os.getppid())
    load_plugins()  # SOFTEVO_PLUGINS: a model or world they register exists here too
    worlds.register_missing(added_worlds)

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the coordinator's to handle
    numba.set_num_threads(1)
    try:
        warm_up(threads=1)
    except Exception:  # a broken simulator shows up in the results, with its error
        traceback.print_exc()
