"""The coordinator loop of ``softevo serve``: drives every unfinished run of the database.

A background thread claims each pending or running run (a lock, so that only one
coordinator drives a run), loads it from the database (a new algorithm, or the state saved
after its last generation) and advances all claimed runs one generation per round with
``service.runs.coordinator.Coordinator.round``, which stores each generation in one transaction
before the next is dispatched. Runs submitted meanwhile join at the next round; cancelled
runs leave at the next round. A coordinator restarted (or another one taking over a lock
that expired) resumes every run from its last stored generation.

Faults heal themselves: a round that fails (the database, Redis or the disk away, or a bug
in the loop's own housekeeping) is logged, everything this coordinator held in memory for
its runs (the runs, their generations in flight, their locks) is dropped, and the next
round reloads the runs from the database once it answers. Only a run's own robots or
settings fail a run (``Coordinator._guard``). A cancel is the run's status in the database:
every coordinator honours it, and a resume (status running again) undoes it.

Locks (``service.runs.locks``): with Redis, a key per run renewed by a thread (``RedisLocks``);
without Redis, the database holds them (``service.storage.advisory_locks.DatabaseLocks``). A coordinator
that finds a run locked by another logs once who holds it and waits: it takes the run over
when the lock is freed.

Several coordinators on one database (with Redis): each counts the coordinators alive now
(``RedisLocks.peers``) and drives at most its share, ``ceil(unfinished runs / peers)``; one
that joins takes the runs the others hand over between generations, and the runs of one
that stops or dies are taken by the others once its locks expire. So coordinator capacity
grows with the number of coordinator processes (docs/cluster.md). Without Redis the first
coordinator drives every run, as above.
"""

from __future__ import annotations

import logging
import math
import threading

from sqlalchemy import Engine

from softevo.evolution.run_status import RunStatus
from softevo.service.runs.coordinator import (
    ActiveRun,
    Coordinator,
    DatabaseUnavailable,
    GenerationReport,
    database_unavailable,
    first_line,
    load_run,
    unfinished_runs,
)
from softevo.service.runs.executors import Executor
from softevo.service.runs.locks import RunLocks, redis_error
from softevo.service.storage.runs import set_run_status

log = logging.getLogger("softevo.coordinator")

class CoordinatorLoop:
    """Drives the database's unfinished runs in a background thread (see the module doc)."""

    def __init__(
        self,
        engine: Engine,
        executor: Executor,
        locks: RunLocks,
        poll_seconds: float = 1.0,
        renew_seconds: float = 10.0,
        stop: threading.Event | None = None,
    ) -> None:
        self.engine = engine
        self.executor = executor
        self.locks = locks
        self.poll_seconds = poll_seconds
        self.renew_seconds = renew_seconds
        self.stop_event = stop or threading.Event()
        self.active: list[ActiveRun] = []
        self.lost: set[int] = set()
        self.waiting: set[int] = set()  # runs locked by another coordinator (logged once)
        self.coordinator = Coordinator(
            engine, executor, on_generation=self._on_generation, holds=getattr(locks, "holds", None)
        )
        self.share = 0  # runs this coordinator drives at most (``_claim``)
        self.driven: set[int] = set()  # every run this coordinator has driven
        self._threads: list[threading.Thread] = []
        self.away: str | None = None  # what cannot be reached now ("Redis", "the database"), said once

    # -- control -----------------------------------------------------------------------------

    def start(self) -> None:
        for target, name in ((self._loop, "coordinator"), (self._renew_loop, "run-locks")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self, timeout: float = 30.0) -> None:
        """Stop after the current wait (an RQ executor sharing ``stop_event`` stops waiting
        at once; the generation in flight is redone by the next coordinator)."""
        self.stop_event.set()
        for thread in self._threads:
            thread.join(timeout)
        self.locks.release([run.run_id for run in self.active])
        try:
            self.locks.leave()
        except Exception as exc:  # Redis away: the others count this one out within the ttl
            log.warning("cannot leave the coordinators' count: %s", exc)

    @property
    def alive(self) -> bool:
        """Whether the loop's thread runs (for /health: a dead loop drives nothing)."""
        return bool(self._threads) and self._threads[0].is_alive()

    def request_cancel(self, run_id: int) -> None:
        """Have the executor drop the cancelled run's evaluations in flight where it can
        (``LocalExecutor.drop_runs``). The cancel itself is the run's status, set by the
        caller; a generation in flight that commits after it keeps it
        (``service.storage.generations``), and the next round leaves the run."""
        self.executor.drop_runs([run_id])

    # -- the loop ----------------------------------------------------------------------------

    def _loop(self) -> None:
        # rq_executor loads rq and redis, which a local coordinator never needs
        from softevo.service.runs.rq_executor import ExecutorStopped

        while not self.stop_event.is_set():
            try:
                driving = self.step()
                if self.away is not None:
                    log.warning("%s can be reached again: the runs go on", self.away)
                    self.away = None
                if not driving:
                    self.stop_event.wait(self.poll_seconds)
            except ExecutorStopped:
                break
            except Exception as exc:  # the loop outlives any failed round
                self._recover(exc)

    def _recover(self, exc: Exception) -> None:
        """After a failed round: say why in one line, drop what this coordinator held for
        its runs (``_reset``) and wait; the next round reloads them from the database.
        Never raises: the database or Redis may still be away."""
        retry = self.poll_seconds * 5
        try:
            runs = ", ".join(f"r{run.run_id}" for run in self.active) or "none driven now"
            if isinstance(exc, DatabaseUnavailable) or database_unavailable(exc):
                cause = exc.__cause__ if isinstance(exc, DatabaseUnavailable) else exc
                self._say_away(
                    "the database", "the database cannot be written or reached (%s); runs paused at "
                    "their last stored generation (%s); retrying every %.0f s, they go on by themselves",
                    first_line(cause), runs, retry,
                )  # fmt: skip
            elif redis_error(exc):
                self._say_away(
                    "Redis", "Redis cannot be reached (%s); runs paused (%s); retrying every %.0f s, "
                    "said again when it is back", first_line(exc), runs, retry,
                )  # fmt: skip
            else:
                log.exception("coordinator round failed (runs %s); reloading them from the database", runs)
        except Exception:  # noqa: BLE001 - logging must not end the loop
            pass
        self._reset()
        self.stop_event.wait(retry)

    def _say_away(self, what: str, message: str, *args) -> None:
        """Log ``message`` once while ``what`` stays away (then at DEBUG level, every retry):
        one line, not one every few seconds; ``_loop`` says when it is back."""
        log.log(logging.DEBUG if self.away == what else logging.WARNING, message, *args)
        self.away = what

    def step(self) -> bool:
        """Claim new runs, drop finished, cancelled or lost ones, advance the rest one
        generation (with an executor that keeps generations in flight: those whose
        generation ends within ``poll_seconds``). Returns whether any run is being driven."""
        self._claim()
        if not self.active:
            return False
        before = {run.run_id for run in self.active}
        if self.coordinator.pipelined:  # each run at its own pace; new runs join within a poll
            self.active = self.coordinator.advance(self.active, timeout=self.poll_seconds)
        else:
            self.active = self.coordinator.round(self.active)
        self.locks.release(before - {run.run_id for run in self.active})
        self._hand_over()
        return True

    def _hand_over(self) -> None:
        """Give up runs beyond this coordinator's share (another coordinator joined), among
        those between generations: whoever takes one resumes it from its stored generation."""
        excess = len(self.active) - self.share
        if excess <= 0:
            return
        idle = [run for run in self.active if run.run_id not in self.coordinator.in_flight][:excess]
        if not idle:
            return
        given = {run.run_id for run in idle}
        self.active = [run for run in self.active if run.run_id not in given]
        self.coordinator.forget(given)
        self.locks.release(given)
        log.info("handed run(s) %s over to the other coordinators (share %d)", sorted(given), self.share)

    def _claim(self) -> None:
        """Hold the unfinished runs of this coordinator's share: ``ceil(unfinished / peers)``
        with the coordinators alive now (``RunLocks.peers``), so several coordinators on one
        database split its runs between them, and take over a stopped one's runs."""
        unfinished = unfinished_runs(self.engine)
        peers = self.locks.peers()
        self.share = math.ceil(len(unfinished) / peers)
        lost, self.lost = self.lost, set()  # swapped, not cleared: the renew thread adds to it
        keep = set(unfinished) - lost
        dropped = [run.run_id for run in self.active if run.run_id not in keep]
        self.active = [run for run in self.active if run.run_id in keep]
        held = {run.run_id for run in self.active}
        # a run dropped (finished, cancelled, lock lost) and loaded again later asks its
        # generation anew: nothing of its old generation in flight may be told to it
        self.coordinator.forget(set(self.coordinator.in_flight) - held)
        self.locks.release(dropped)
        for run_id in unfinished:
            if run_id in held:
                continue
            if len(self.active) >= self.share:  # the others' share
                break
            if not self.locks.acquire(run_id):
                self._waits_for(run_id, shared=peers > 1)
                continue
            self.waiting.discard(run_id)
            try:
                run = load_run(self.engine, run_id)
                self._mark_running(run_id)
            except Exception as exc:
                self.locks.release([run_id])
                if database_unavailable(exc):
                    raise  # paused: _recover, then loaded again
                log.exception("run %d failed: its stored state cannot be loaded", run_id)
                self._set_status(run_id, RunStatus.FAILED, f"its stored state cannot be loaded: {exc}")
                continue
            self.executor.keep_runs([run_id])  # resumed after a cancel: evaluate its tasks again
            log.info("driving run %d from generation %d", run_id, run.next_generation)
            self.active.append(run)
            self.driven.add(run_id)

    def _waits_for(self, run_id: int, shared: bool = False) -> None:
        """Say once why a run is not driven here: a warning when this coordinator is alone (a
        stopped one's lock has yet to expire), news when peers split the runs by design."""
        if run_id in self.waiting:
            return
        self.waiting.add(run_id)
        describe = getattr(self.locks, "holder", None)
        try:
            who = describe(run_id) if describe else "its lock is taken"
        except Exception as exc:  # the description must not stop the loop
            who = f"its lock is taken ({exc})"
        level = logging.INFO if shared else logging.WARNING
        log.log(level, "run %d is driven by another coordinator: %s; waiting for its lock", run_id, who)

    def _reset(self) -> None:
        """Forget the runs driven, their generations in flight and their locks (which
        expire by themselves if Redis or the database cannot be told now)."""
        held = [run.run_id for run in self.active]
        self.active = []
        self.coordinator.forget(list(self.coordinator.in_flight))
        try:
            self.locks.release(held)
        except Exception as exc:  # noqa: BLE001 - Redis or the database away
            log.warning("cannot release the locks of run(s) %s now (%s); they expire", held, first_line(exc))

    def _renew_loop(self) -> None:
        while not self.stop_event.wait(self.renew_seconds):
            try:
                lost = self.locks.renew()
            except Exception as exc:  # Redis away: the locks are re-taken once it is back
                log.warning("cannot renew run locks: %s", exc)
                continue
            if lost:
                log.warning("lost the lock of run(s) %s to another coordinator", sorted(lost))
                self.lost |= lost

    def _on_generation(self, report: GenerationReport) -> None:
        log.info(
            "run %d generation %d/%d stored (best %.3f, %d evaluations, %.1f s of simulation)",
            report.run_id,
            report.generation + 1,
            report.generations,
            report.best_distance,
            report.evaluations,
            report.evaluation_seconds,
        )

    def _mark_running(self, run_id: int) -> None:
        """pending -> running (a run cancelled meanwhile stays cancelled)."""
        with self.engine.begin() as conn:
            set_run_status(conn, run_id, RunStatus.RUNNING, only_from=(RunStatus.PENDING,))

    def _set_status(self, run_id: int, status: RunStatus, error: str | None = None) -> None:
        with self.engine.begin() as conn:
            set_run_status(conn, run_id, status, error)
