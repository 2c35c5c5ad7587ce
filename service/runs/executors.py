"""Executors: where evaluation tasks run. One small interface, several implementations.

An executor takes a list of JSON tasks (``worker.tasks.Task.to_json``) and returns their
JSON results (``worker.tasks.TaskResult.to_json``) in the same order (``Executor`` is the
whole interface; the coordinator calls nothing else). ``InlineExecutor`` runs them in this
process (tests, one core); ``LocalExecutor`` spreads them over a process pool, one numba
thread per process, many genomes per pool task; both evaluate a batch before they return
(``BlockingExecutor``'s defaults). ``service.runs.rq_executor`` has an RQ executor with the
same interface that keeps generations in flight.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any, Protocol

from softevo.evolution import environments as worlds
from softevo.service.settings import GENOMES_PER_TASK
from softevo.worker.evaluate import ensure_compiled, evaluate_batch, init_pool_process
from softevo.worker.tasks import failed

EXECUTOR_KINDS = ("local", "rq")  # LocalExecutor (a process pool) and rq_executor.RQExecutor
TaskJSON = dict[str, Any]  # worker.tasks.Task.to_json()
ResultJSON = dict[str, Any]  # worker.tasks.TaskResult.to_json()
CANCELLED = "run cancelled: evaluation dropped"
DROP_POLL_SECONDS = 0.25  # how often an evaluation in flight looks for cancelled runs


class Ticket(Protocol):
    """One ``submit``'s evaluation: ``done`` once every task has its result, ``results`` then
    in the tasks' order."""

    results: list[ResultJSON | None]

    @property
    def done(self) -> bool: ...


class Executor(Protocol):
    """Evaluates tasks; ``workers`` is how many evaluate at once (for progress estimates).

    ``pipelined``: whether runs go at their own pace, several generations in flight
    (``submit`` / ``wait``); otherwise the coordinator evaluates a round of every run's
    genomes in one ``evaluate``. ``drop_runs`` / ``keep_runs``: cancelled runs' evaluations in
    flight dropped where the executor can, and taken again when the runs resume."""

    workers: int
    pipelined: bool

    def evaluate(self, tasks: list[TaskJSON]) -> list[ResultJSON]:
        """Results of ``tasks``, in order."""
        ...

    def submit(self, tasks: list[TaskJSON]) -> Ticket:
        """Start evaluating ``tasks`` (one run's generation); ``wait`` says when it is done."""
        ...

    def wait(self, tickets: Iterable[Ticket], timeout: float | None = None) -> list[Ticket]:
        """The tickets among ``tickets`` that are done, once one is (or ``timeout`` seconds)."""
        ...

    def drop_runs(self, run_ids: Iterable[int]) -> None:
        """Drop the evaluations of ``run_ids`` (cancelled runs) where possible."""
        ...

    def keep_runs(self, run_ids: Iterable[int]) -> None:
        """Evaluate the tasks of ``run_ids`` again (runs resumed after a cancel)."""
        ...

    def close(self) -> None:
        """Release processes or connections."""
        ...


@dataclass
class Evaluated:
    """The ticket of an executor that evaluates in ``submit``: done at once."""

    results: list[ResultJSON | None]
    done: bool = True


class BlockingExecutor:
    """What an executor that evaluates a batch before it returns has of ``Executor``:
    ``submit`` evaluates at once, so nothing is ever in flight (not ``pipelined``), and no run
    is dropped. Subclasses write ``evaluate`` and set ``workers``."""

    workers: int = 1
    pipelined = False

    def evaluate(self, tasks: list[TaskJSON]) -> list[ResultJSON]:
        raise NotImplementedError

    def submit(self, tasks: list[TaskJSON]) -> Evaluated:
        return Evaluated(list(self.evaluate(tasks)))

    def wait(self, tickets: Iterable[Ticket], timeout: float | None = None) -> list[Ticket]:
        return [ticket for ticket in tickets if ticket.done]

    def drop_runs(self, run_ids: Iterable[int]) -> None:
        """Nothing to drop: evaluations under way finish, and the coordinator leaves a
        cancelled run's results unstored."""

    def keep_runs(self, run_ids: Iterable[int]) -> None:
        """Nothing dropped, nothing to take again."""

    def close(self) -> None:
        """Nothing to release."""


class InlineExecutor(BlockingExecutor):
    """Evaluates in the calling process, all robots in one ``simulate_many`` call."""

    def __init__(self, threads: int | None = 1) -> None:

        ensure_compiled()
        self.threads = threads
        self.workers = threads or 1

    def evaluate(self, tasks: list[TaskJSON]) -> list[ResultJSON]:

        return evaluate_batch(tasks, threads=self.threads) if tasks else []


def chunks(tasks: list[TaskJSON], workers: int, per_task: int) -> list[list[TaskJSON]]:
    """Split tasks into pool jobs of at most ``per_task`` genomes, at least one per worker."""
    if not tasks:
        return []
    size = max(1, min(per_task, math.ceil(len(tasks) / workers)))
    return [tasks[i : i + size] for i in range(0, len(tasks), size)]


class LocalExecutor(BlockingExecutor):
    """A process pool over ``workers`` processes (default: all cores).

    Processes start with the ``spawn`` method (no fork of a process holding numba threads or
    database connections) and warm the simulator once each. ``drop_runs`` drops a cancelled
    run's tasks from the evaluation in flight: pool jobs not started are cancelled, and when
    one is already running the pool's processes are ended and the other runs' jobs run again
    on a new pool.
    """

    def __init__(
        self,
        workers: int | None = None,
        genomes_per_task: int = GENOMES_PER_TASK,
        job: Callable[..., list] | None = None,
    ) -> None:

        ensure_compiled()  # before the pool: its processes then all load the cached kernels
        self.workers = workers or os.cpu_count() or 1
        self.genomes_per_task = genomes_per_task
        self.job = job or evaluate_batch  # a module-level function (the pool pickles it by name)
        self._pool = self._new_pool()
        self._dropped: set[int] = set()  # cancelled runs (drop_runs), from any thread
        self._drop_lock = threading.Lock()

    def _new_pool(self) -> ProcessPoolExecutor:

        return ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=init_pool_process,
            initargs=(worlds.added(),),
        )

    def drop_runs(self, run_ids: Iterable[int]) -> None:
        """Drop the tasks of ``run_ids`` (cancelled runs) now and from every later call: their
        results read as failed evaluations (``CANCELLED``), which the coordinator does not
        store. Thread-safe: the API's cancel calls it while ``evaluate`` waits."""
        with self._drop_lock:
            self._dropped.update(int(run_id) for run_id in run_ids)

    def keep_runs(self, run_ids: Iterable[int]) -> None:
        """Evaluate the tasks of ``run_ids`` again (runs resumed after a cancel)."""
        with self._drop_lock:
            self._dropped.difference_update(int(run_id) for run_id in run_ids)

    def evaluate(self, tasks: list[TaskJSON]) -> list[ResultJSON]:
        """Results in order. A process that dies (a crash inside compiled code) breaks the
        pool: it is restarted and the unfinished genomes are evaluated one per job, so the
        genome that kills a process again is recorded as failed, not retried forever. Jobs
        wholly of dropped runs (``drop_runs``) end at once, while they wait or run."""
        parts = chunks(tasks, self.workers, self.genomes_per_task)
        results: list[list[ResultJSON] | None] = [None] * len(parts)
        jobs = {index: self._pool.submit(self.job, part) for index, part in enumerate(parts)}
        while jobs:
            wait(list(jobs.values()), timeout=DROP_POLL_SECONDS, return_when=FIRST_COMPLETED)
            jobs = self._drop(parts, jobs, results)
            for index, job in list(jobs.items()):
                if not job.done():
                    continue
                del jobs[index]
                try:
                    results[index] = job.result()
                except BrokenProcessPool:
                    self._restart()
                    results[index] = self._one_by_one(parts[index])
        return [result for part in results for result in part or []]

    def _drop(
        self, parts: list[list[TaskJSON]], jobs: dict[int, Future], results: list[list[ResultJSON] | None]
    ) -> dict[int, Future]:
        """The jobs still to wait for, once those wholly of dropped runs are answered
        ``CANCELLED``: cancelled if they wait, else every pool process is ended and the
        other unfinished jobs are submitted again to a new pool."""
        with self._drop_lock:
            dropped = set(self._dropped)
        doomed = [i for i in jobs if dropped and all(task.get("run_id") in dropped for task in parts[i])]
        if not doomed:
            return jobs
        running = False
        for index in doomed:
            results[index] = [failed(task, CANCELLED).to_json() for task in parts[index]]
            running |= not jobs.pop(index).cancel()
        if not running:
            return jobs
        self._end_processes()
        again = {}
        for index, job in jobs.items():
            if job.done() and not job.cancelled() and job.exception() is None:
                results[index] = job.result()
            else:  # broken by the ending, or not run yet: again on the new pool
                again[index] = self._pool.submit(self.job, parts[index])
        return again

    def _end_processes(self) -> None:
        """End every pool process now (one runs a dropped job) and start a new pool.
        ``ProcessPoolExecutor`` has no public way to end its processes before Python 3.14."""
        processes = list((getattr(self._pool, "_processes", None) or {}).values())
        for process in processes:
            process.terminate()
        self._pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.join(10)
        self._pool = self._new_pool()

    def _one_by_one(self, tasks: list[TaskJSON]) -> list[ResultJSON]:

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


def make_executor(workers: int | None = None, genomes_per_task: int = GENOMES_PER_TASK) -> Executor:
    """The local executor; ``workers=0`` evaluates inline in this process."""
    if workers == 0:
        return InlineExecutor()
    return LocalExecutor(workers, genomes_per_task)
