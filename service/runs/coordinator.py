"""The coordinator: ask -> dispatch -> tell -> persist, one transaction per generation.

Many runs advance together. With an executor that keeps several generations in flight
(``Executor.pipelined``: the RQ executor), each run goes at its own pace (``advance``): as soon
as one run's generation has all its results, it is told them, committed and its next
generation dispatched, while the other runs' jobs keep the workers busy; no run waits
for another's slowest evaluation. With the others (in-process, process pool) each round asks
every active run for its next generation, sends all their tasks in one call, then tells each
run its results (``round``). Either way each run's generation (individuals, evaluations,
population, summary and the algorithm's JSON state, RNG included) is committed in one
transaction before that run's next generation is dispatched, and a run's results do not
depend on the order in which runs finish. A coordinator killed at any point resumes from
the last committed generation and reaches exactly the results of an uninterrupted run: the
state it restarts from is the state the uninterrupted run had, and evaluations are
deterministic.

Each generation's stats count the simulations (``evaluations``) and the evaluations that
needed none (``reused``: a living twin's in the same world; ``empty_bodies``); survivors are
never simulated again in the world they were evaluated in (``Evolution.ask`` refuses).

Environment switch: at the first generation of a new environment in the treatment's
``Schedule`` the algorithm first breeds as usual, then ``Schedule.switch`` moves survivors
and offspring into the new environment (``reevaluate_all``), and they are all evaluated
there in that same generation. ``evolution.runner.ask_generation`` does this for the
coordinator and for the local run loop (``evolution.runner.run``, ``softevo.evolve``) alike,
so a local run with the same seed evaluates the same individuals in the same worlds.
"""

from __future__ import annotations

import logging
import traceback
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy import Engine
from sqlalchemy.exc import DBAPIError, InterfaceError, OperationalError

from softevo.errors import UserError
from softevo.evolution import traits
from softevo.evolution.algorithm import Evolution
from softevo.evolution.run_status import RunStatus
from softevo.evolution.runner import ask_generation, tell_generation
from softevo.evolution.selection import non_dominated_sort, objective_matrix
from softevo.evolution.treatments import Treatment
from softevo.service.runs.executors import Executor
from softevo.service.runs.locks import RunLocks, holding, locks_for
from softevo.service.storage.generations import GenerationRecord, record_generation
from softevo.service.storage.runs import active_run_ids, run_row, set_run_status
from softevo.worker.tasks import TaskResult, generation_tasks

log = logging.getLogger("softevo.coordinator")

SQLITE_UNAVAILABLE = ("disk", "full", "readonly", "read-only", "locked", "unable to open", "i/o")


class DatabaseUnavailable(UserError):
    """The database cannot be reached or written (server down, disk full, read-only file):
    the run pauses at its last stored generation instead of failing; ``softevo serve``
    retries, ``softevo run``/``resume`` stop with this one line (exit status 2)."""


class LockLost(RuntimeError):
    """This coordinator no longer holds the run's lock: another one drives it."""


def database_unavailable(exc: BaseException) -> bool:
    """Whether ``exc`` says the database is away or cannot be written (not a bug in a run)."""
    if isinstance(exc, DBAPIError) and exc.connection_invalidated:
        return True
    if isinstance(exc, InterfaceError):
        return True
    if not isinstance(exc, OperationalError):
        return False
    if type(exc.orig).__module__.startswith("sqlite3"):  # sqlite3 says OperationalError for bugs too
        return any(word in str(exc.orig).lower() for word in SQLITE_UNAVAILABLE)
    return True


def first_line(exc: BaseException | None) -> str:
    """The first line of what an exception says (a driver's own, where SQLAlchemy wraps
    one: its message without SQLAlchemy's SQL and links)."""
    inner = getattr(exc, "orig", None) or exc
    lines = str(inner).strip().splitlines()
    return lines[0] if lines else type(inner).__name__


def failure_words(exc: BaseException, doing: str) -> str:
    """What went wrong, in words, for a run's stored error: what the coordinator was doing,
    the exception, and where it was raised (the traceback goes to the log)."""
    where = ""
    frames = traceback.extract_tb(exc.__traceback__)
    if frames:
        last = frames[-1]
        where = f" (in {last.name}, {Path(last.filename).name} line {last.lineno})"
    return f"{doing} failed: {type(exc).__name__}: {first_line(exc)}{where}"


@dataclass(frozen=True)
class GenerationReport:
    """What the coordinator tells its progress listener after each committed generation."""

    run_id: int
    generation: int
    generations: int
    best_distance: float
    evaluations: int
    evaluation_seconds: float  # the evaluations' own simulation time (``evaluation_seconds``)
    finished: bool


@dataclass
class ActiveRun:
    """A run being advanced: its treatment, algorithm and the generation to do next."""

    run_id: int
    treatment: Treatment
    algorithm: Any  # evolution.algorithm.Evolution
    next_generation: int
    generations: int
    pending: list[Any] | None = None  # the generation's individuals (evaluated or not)
    asked: list[Any] | None = None  # those needing a simulation

    @property
    def done(self) -> bool:
        return self.next_generation >= self.generations


def load_run(engine: Engine, run_id: int) -> ActiveRun:
    """The run as stored: a new algorithm, or the one saved after its last generation."""

    with engine.connect() as conn:
        row = run_row(conn, run_id)
    treatment = Treatment.from_settings(row["settings"])
    if row["algorithm_state"] is None:
        algorithm = Evolution(treatment.evolution_config(row["seed"]))
    else:
        algorithm = Evolution.from_state_dict(row["algorithm_state"])
    return ActiveRun(run_id, treatment, algorithm, row["generation"] + 1, row["generations"])


def unfinished_runs(engine: Engine, run_ids: Sequence[int] | None = None) -> list[int]:
    """Ids of pending or running runs (among ``run_ids`` if given)."""
    with engine.connect() as conn:
        return active_run_ids(conn, run_ids)


def ask(run: ActiveRun) -> list[dict[str, Any]]:
    """Ask the run's algorithm for its next generation (``evolution.runner.ask_generation``,
    as the local run loop asks); return the evaluation tasks."""
    algorithm, generation = run.algorithm, run.next_generation
    asked = ask_generation(algorithm, run.treatment.schedule(), generation)
    run.pending, run.asked = list(algorithm.pending), asked
    # run_id: for job ids and worker logs; evaluate_batch ignores it
    return generation_tasks(algorithm, asked, generation, run_id=run.run_id)


def tell(run: ActiveRun, results: list[dict[str, Any]], seconds: float) -> GenerationRecord:
    """Tell the algorithm its results (``worker.tasks.TaskResult`` JSON: their outcomes);
    return the generation's record for the database."""
    by_id = {result.id: result for result in map(TaskResult.from_json, results)}
    tell_generation(run.algorithm, run.asked, {ind_id: result.outcome for ind_id, result in by_id.items()})
    record = GenerationRecord(run.run_id, run.next_generation)
    record.individuals = [
        _individual_row(run, ind, by_id.get(ind.id))
        for ind in run.pending
        if ind.generation_born == run.next_generation
    ]
    record.evaluations = [_evaluation_row(run, ind, by_id.get(ind.id)) for ind in run.pending]
    record.members = _member_rows(run)
    record.summary = _summary(run, len(results), seconds)
    record.state = run.algorithm.state_to_dict()
    record.finished = run.next_generation + 1 >= run.generations
    record.failure = failure_reason(run)
    return record


FAILED_SHARE_LIMIT = 0.95  # a generation whose simulations fail this often fails its run


def failure_reason(run: ActiveRun) -> str | None:
    """Why the run fails with its generation just told, or None: at least
    ``FAILED_SHARE_LIMIT`` of the generation's simulations failed (unstable, over the step
    budget, crashed). Evolution cannot select among failures: every failed robot scores
    ``FAILED_DISTANCE``, so such a run would go on to its last generation and say
    "finished" with a best of 0. The reason names the most common error, with an example."""
    simulated = run.asked or []
    failed = [ind for ind in simulated if ind.failed]
    if not simulated or len(failed) < FAILED_SHARE_LIMIT * len(simulated):
        return None
    kinds = Counter(str(ind.error).split(":")[0] for ind in failed)
    kind, count = kinds.most_common(1)[0]
    example = next(str(ind.error) for ind in failed if str(ind.error).split(":")[0] == kind)
    return (f"{len(failed)} of {len(simulated)} evaluations of generation {run.next_generation} failed "
            f"(a run fails at {FAILED_SHARE_LIMIT:.0%}); most often ({count}): {example}")


def _individual_row(run: ActiveRun, ind, result: TaskResult | None) -> dict[str, Any]:
    phenotype = result.phenotype if result else None
    if phenotype is None:
        phenotype = ind.phenotype(run.algorithm.config.encoding).summary()
    return {
        "local_id": ind.id,
        "parent_local_id": ind.parent_id,
        "generation_born": ind.generation_born,
        "genome": ind.genome.to_dict(),
        "phenotype": phenotype,
    }


def _objectives_with_body(run: ActiveRun, ind) -> dict[str, float]:
    """The individual's objectives over its phenotype's active_share and voxel_count, so
    that the paper's three (distance, active_share, voxel_count) are there whichever
    objectives its run selects on (a treatment's objectives always include distance)."""
    phenotype = ind.phenotype(run.algorithm.config.encoding)
    return {"active_share": phenotype.active_share, "voxel_count": float(phenotype.voxel_count),
            **ind.objectives}


def _trait_columns(run: ActiveRun, ind) -> dict[str, Any]:
    """{name: value} of each trait with a column of its own (``evolution.traits``): from the
    objectives, else the body, else the descriptors (``Individual.trait_values``, which the
    MAP-Elites archive reads too); a count as an int, a trait every evaluation has
    (``required``) KeyError when missing, never None."""
    measured = ind.trait_values(run.algorithm.config.encoding, traits.columns())
    values: dict[str, Any] = {}
    for trait in traits.column_traits():
        value = measured[trait.name] if trait.required else measured.get(trait.name)
        values[trait.name] = int(value) if trait.integer and value is not None else value
    return values


def _evaluation_row(run: ActiveRun, ind, result: TaskResult | None) -> dict[str, Any]:
    return {
        "local_id": ind.id,
        "generation": run.next_generation,
        "age": ind.age,
        "environment": ind.environment,
        "stiffness": run.treatment.stiffness_pa,
        **_trait_columns(run, ind),
        "descriptors": ind.descriptors,
        "objectives": dict(ind.objectives),
        "stable": bool(ind.stable),
        "error": ind.error,
        "seconds": result.seconds if result else None,
        "steps": result.outcome.steps if result else None,
        "simulated_seconds": result.outcome.simulated_seconds if result else None,
    }


def front_ranks(run: ActiveRun) -> list[int]:
    """Front rank (0 = non-dominated) of each survivor over the treatment's objectives
    (age excluded); failed evaluations rank behind every successful one."""

    population = run.algorithm.population
    valid = np.array([not ind.failed for ind in population], dtype=bool)
    ranks = np.zeros(len(population), dtype=int)
    if valid.any():
        rows = [ind.objectives for ind, ok in zip(population, valid, strict=True) if ok]
        ranks[valid] = non_dominated_sort(objective_matrix(rows, run.algorithm.config.objectives))
        ranks[~valid] = ranks[valid].max() + 1
    return [int(rank) for rank in ranks]


def _member_rows(run: ActiveRun) -> list[dict[str, Any]]:
    ranks = front_ranks(run)
    return [
        {"local_id": ind.id, "front_rank": rank, "age": ind.age}
        for ind, rank in zip(run.algorithm.population, ranks, strict=True)
    ]


def evaluation_seconds(results: list[dict[str, Any]]) -> float:
    """A generation's evaluation time, seconds: the sum of its results' own ``seconds``
    (each the worker's simulation time, a batch's shared among its tasks), so that the time
    tasks waited in a queue or travelled to a worker is not counted."""
    return float(sum(result.get("seconds") or 0.0 for result in results))


def _summary(run: ActiveRun, simulated: int, seconds: float) -> dict[str, Any]:
    population = run.algorithm.population
    distances = [ind.objectives["distance"] for ind in population]
    bodies = [_objectives_with_body(run, ind) for ind in population]
    ranks = front_ranks(run)
    return {
        "environment": run.treatment.environment_at(run.next_generation),
        "evaluations": simulated,
        "evaluation_seconds": seconds,
        "best_distance": max(distances),
        "mean_distance": float(np.mean(distances)),
        "front_size": ranks.count(0),
        "failed": sum(1 for ind in run.pending if ind.failed),
        # evaluated without a simulation: a living twin's evaluation in the same world, or an
        # empty body (survivors are never simulated again in their world: Evolution.ask)
        "reused": run.algorithm.not_simulated["reused"],
        "empty_bodies": run.algorithm.not_simulated["empty"],
        "passive_bodies": run.algorithm.not_simulated["passive"],  # no active voxel: distance 0
        "mean_voxel_count": float(np.mean([body["voxel_count"] for body in bodies])),
        "mean_active_share": float(np.mean([body["active_share"] for body in bodies])),
        "best_local_id": population[int(np.argmax(distances))].id,
    }


class Coordinator:
    """Advances runs to their end, persisting each generation before dispatching the next."""

    def __init__(
        self,
        engine: Engine,
        executor: Executor,
        on_generation: Callable[[GenerationReport], None] | None = None,
        holds: Callable[[int], bool] | None = None,
    ) -> None:
        self.engine = engine
        self.executor = executor
        self.on_generation = on_generation
        # whether this coordinator still holds a run's lock, asked before each commit (None:
        # always): one that lost it (Redis emptied, another took the run) stores nothing more
        self.holds = holds

        self.in_flight: dict[int, tuple[ActiveRun, Any]] = {}  # run id -> (run, executor ticket)

    @property
    def pipelined(self) -> bool:
        """Whether runs go at their own pace: the executor keeps generations in flight
        (``submit`` / ``wait``; ``Executor.pipelined``)."""
        return self.executor.pipelined

    def run(
        self, run_ids: Sequence[int], max_rounds: int | None = None, locks: RunLocks | None = None
    ) -> None:
        """Advance the unfinished runs among ``run_ids`` until all are done (or cancelled,
        or failed), or for at most ``max_rounds`` more generations each (``softevo run`` and
        ``resume``). Each run's lock is taken first, as ``softevo serve`` takes it
        (``service.runs.locks.locks_for``): a run a server drives is left to it, said in one line."""
        locks = locks_for(self.engine) if locks is None else locks
        with holding(locks, unfinished_runs(self.engine, run_ids)) as held:
            holds, self.holds = self.holds, getattr(locks, "holds", None)
            try:
                self._run(held, max_rounds)
            finally:
                self.holds = holds

    def _run(self, run_ids: list[int], max_rounds: int | None) -> None:
        runs = [load_run(self.engine, run_id) for run_id in run_ids]
        if self.pipelined:
            limit = {run.run_id: run.next_generation + (max_rounds or run.generations) for run in runs}
            while runs:
                runs = [run for run in self.advance(self._still_active(runs))
                        if run.run_id in self.in_flight or run.next_generation < limit[run.run_id]]
            return
        rounds = 0
        while runs and (max_rounds is None or rounds < max_rounds):
            runs = self.round(self._still_active(runs))
            rounds += 1

    def advance(self, runs: list[ActiveRun], timeout: float | None = None) -> list[ActiveRun]:
        """Dispatch the next generation of every run of ``runs`` not in flight, wait (at most
        ``timeout`` seconds; None: until one is done) for generations to finish, tell and
        commit those; return the runs that go on (those still in flight among them). Runs
        left out of ``runs`` are forgotten (``forget``)."""
        self.forget(set(self.in_flight) - {run.run_id for run in runs})
        # a run loaded again (another object) asks its generation anew: the old one's
        # generation in flight is not its own (the same jobs: their results are taken)
        self.forget([run.run_id for run in runs if self.in_flight.get(run.run_id, (run,))[0] is not run])
        going_on = []
        for run in runs:
            if run.run_id not in self.in_flight:
                tasks = self._guard(run, f"breeding generation {run.next_generation}", ask, run)
                if tasks is None:  # failed: marked so by _guard
                    continue
                self.in_flight[run.run_id] = (run, self.executor.submit(tasks))
            going_on.append(run)
        tickets = [ticket for _, ticket in self.in_flight.values()]
        done = {id(ticket) for ticket in self.executor.wait(tickets, timeout)}
        finished = [run for run in going_on if id(self.in_flight[run.run_id][1]) in done]
        live = self._live(finished)
        for run in finished:
            _, ticket = self.in_flight.pop(run.run_id)
            if run.run_id not in live:  # cancelled while in flight: its generation is dropped
                going_on.remove(run)
                continue
            results = ticket.results
            storing = f"storing generation {run.next_generation}"
            stored = self._guard(run, storing, self._finish, run, results, evaluation_seconds(results))
            if not stored or run.done:
                going_on.remove(run)
        return going_on

    def forget(self, run_ids) -> None:
        """Stop waiting for these runs' generations in flight (cancelled, lost, reloaded):
        their jobs may still run; a run loaded again asks the same generation, whose jobs
        have the same ids, and takes their results."""
        for run_id in list(run_ids):
            self.in_flight.pop(run_id, None)

    def round(self, runs: list[ActiveRun]) -> list[ActiveRun]:
        """One generation of every run; returns the runs that go on."""
        asked: list[tuple[ActiveRun, list[dict]]] = []
        for run in runs:
            tasks = self._guard(run, f"breeding generation {run.next_generation}", ask, run)
            if tasks is not None:
                asked.append((run, tasks))
        tasks = [task for _, run_tasks in asked for task in run_tasks]
        results = self.executor.evaluate(tasks)
        live = self._live([run for run, _ in asked])
        going_on, offset = [], 0
        for run, run_tasks in asked:
            run_results = results[offset : offset + len(run_tasks)]
            offset += len(run_tasks)
            if run.run_id not in live:  # cancelled while in flight: its generation is dropped
                continue
            storing = f"storing generation {run.next_generation}"
            if self._guard(run, storing, self._finish, run, run_results, evaluation_seconds(run_results)):
                going_on.append(run)
        return [run for run in going_on if not run.done]

    def _live(self, runs: list[ActiveRun]) -> set[int]:
        """Ids of ``runs`` still pending or running: one cancelled while its generation was
        in flight has that generation dropped. A database out of reach counts them all live
        (``_finish`` then says what the database did)."""
        ids = [run.run_id for run in runs]
        try:
            return set(unfinished_runs(self.engine, ids)) if ids else set()
        except Exception as exc:
            if not database_unavailable(exc):
                raise
            return set(ids)

    def _finish(self, run: ActiveRun, results: list[dict], seconds: float) -> bool:
        if self.holds is not None and not self.holds(run.run_id):
            raise LockLost(run.run_id)
        record = tell(run, results, seconds)
        with self.engine.begin() as conn:
            record_generation(conn, record)
        run.next_generation += 1
        if self.on_generation:
            self.on_generation(
                GenerationReport(
                    run.run_id,
                    record.generation,
                    run.generations,
                    record.summary["best_distance"],
                    len(results),
                    seconds,
                    record.finished,
                )
            )
        return True

    def _guard(self, run: ActiveRun, doing: str, function, *args):
        """Call ``function`` (``doing``, in words); a bug in one run marks it failed, logged
        in one line with the traceback after it, and the others go on. A database that
        cannot be reached or written fails no run: ``DatabaseUnavailable``."""
        try:
            return function(*args)
        except LockLost:
            log.warning(
                "run %d is driven by another coordinator now (its lock was lost): this one "
                "drops its generation %d and leaves the run", run.run_id, run.next_generation,
            )  # fmt: skip
            return None
        except Exception as exc:
            if database_unavailable(exc):
                reason = first_line(exc)
                raise DatabaseUnavailable(
                    f"the database cannot be written or reached ({reason}); run {run.run_id} is "
                    f"paused after generation {run.next_generation - 1}, every generation before "
                    f"is stored: free space or restart the database, then softevo resume r{run.run_id}"
                ) from exc
            words = failure_words(exc, doing)
            log.error("run %d failed: %s", run.run_id, words, exc_info=True)
            error = f"{words}; the traceback is in the coordinator's log"
            with self.engine.begin() as conn:
                set_run_status(conn, run.run_id, RunStatus.FAILED, error)
            return None

    def _still_active(self, runs: list[ActiveRun]) -> list[ActiveRun]:
        """Drop runs cancelled (or otherwise stopped) in the database meanwhile."""
        active = set(unfinished_runs(self.engine, [run.run_id for run in runs]))
        return [run for run in runs if run.run_id in active]
