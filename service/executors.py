"""Executors: where evaluation tasks run. One small interface, several implementations.

An executor takes a list of JSON tasks (``worker.tasks.Task.to_json``) and returns their
JSON results (``worker.tasks.Result.to_json``) in the same order. ``InlineExecutor`` runs
them in this process (tests, one core); ``LocalExecutor`` spreads them over a process pool,
one numba thread per process, many genomes per pool task; ``service.rq_executor`` has an
RQ executor with the same interface.
"""

from __future__ import annotations

import math
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Protocol

from softevo.worker.evaluate import ensure_compiled, evaluate_batch, init_pool_process
from softevo.worker.tasks import failed

Task = dict[str, Any]


class Executor(Protocol):
    """Evaluates tasks; ``workers`` is how many evaluate at once (for progress estimates)."""

    workers: int

    def evaluate(self, tasks: list[Task]) -> list[Task]:
        """Results of ``tasks``, in order."""
        ...

    def close(self) -> None:
        """Release processes or connections."""
        ...


class InlineExecutor:
    """Evaluates in the calling process, all robots in one ``simulate_many`` call."""

    def __init__(self, threads: int | None = 1) -> None:

        ensure_compiled()
        self.threads = threads
        self.workers = threads or 1

    def evaluate(self, tasks: list[Task]) -> list[Task]:

        return evaluate_batch(tasks, threads=self.threads) if tasks else []

    def close(self) -> None:
        """Nothing to release."""


def chunks(tasks: list[Task], workers: int, per_task: int) -> list[list[Task]]:
    """Split tasks into pool jobs of at most ``per_task`` genomes, at least one per worker."""
    if not tasks:
        return []
    size = max(1, min(per_task, math.ceil(len(tasks) / workers)))
    return [tasks[i : i + size] for i in range(0, len(tasks), size)]


class LocalExecutor:
    """A process pool over ``workers`` processes (default: all cores).

    Processes start with the ``spawn`` method (no fork of a process holding numba threads or
    database connections) and warm the simulator once each.
    """

    def __init__(
        self, workers: int | None = None, genomes_per_task: int = 4, job: Callable[..., list] | None = None
    ) -> None:

        ensure_compiled()  # before the pool: its processes then all load the cached kernels
        self.workers = workers or os.cpu_count() or 1
        self.genomes_per_task = genomes_per_task
        self.job = job or evaluate_batch  # a module-level function (the pool pickles it by name)
        self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:

        return ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=init_pool_process,
        )

    def evaluate(self, tasks: list[Task]) -> list[Task]:
        """Results in order. A process that dies (a crash inside compiled code) breaks the
        pool: it is restarted and the unfinished genomes are evaluated one per job, so the
        genome that kills a process again is recorded as failed, not retried forever."""
        parts = chunks(tasks, self.workers, self.genomes_per_task)
        jobs = [self._pool.submit(self.job, part) for part in parts]
        results: list[Task] = []
        for part, job in zip(parts, jobs, strict=True):
            try:
                results.extend(job.result())
            except BrokenProcessPool:
                self._restart()
                results.extend(self._one_by_one(part))
        return results

    def _one_by_one(self, tasks: list[Task]) -> list[Task]:

        results = []
        for task in tasks:
            try:
                results.extend(self._pool.submit(self.job, [task]).result())
            except BrokenProcessPool:
                self._restart()
                results.append(failed(task, "the evaluation killed its worker process").to_json())
        return results

    def _restart(self) -> None:
        self._pool.shutdown(wait=False, cancel_futures=True)
        self._pool = self._new_pool()

    def warm(self) -> None:
        """Start every process now (their start-up is otherwise paid by the first batch)."""
        for job in [self._pool.submit(os.getpid) for _ in range(self.workers)]:
            job.result()

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


def make_executor(workers: int | None = None, genomes_per_task: int = 4) -> Executor:
    """The local executor; ``workers=0`` evaluates inline in this process."""
    if workers == 0:
        return InlineExecutor()
    return LocalExecutor(workers, genomes_per_task)
