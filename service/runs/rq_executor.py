"""The RQ executor: evaluation batches as RQ jobs on Redis, evaluated by ``softevo worker``
processes on any machine that reaches the same Redis.

The interface of ``service.runs.executors.Executor`` (``evaluate(tasks) -> results`` in order,
``submit`` / ``wait`` for generations in flight, ``workers``, ``close``). What travels:

- A job calls ``worker.evaluate.evaluate_batch`` by its dotted name (the coordinator never
  imports numba) with a list of JSON tasks, through RQ's JSON serializer (never pickle), and
  returns plain JSON results.
- Job ids are ``run<run>-gen<generation>-batch<b>-<digest>``: the digest is a hash of the
  batch's tasks, so the same batch always has the same id. A resubmitted batch (coordinator
  restarted, Redis emptied, job lost) finds its finished job and takes the stored result, or
  waits for the queued or running one; two databases sharing one Redis never share a job.
- The executor learns which jobs ended from one Redis stream per queue, which workers append
  to after storing each result (``worker.rq_worker.done_stream``); a poll then reads the
  statuses and results of just those jobs, in one round trip each. Every job in flight is
  looked at once per ``maintenance_seconds`` as well, for jobs lost, stopped or announced
  while nobody read.
- Each job has a timeout and ``Retry(max=retries)``. A worker SIGKILLed mid-job stops
  refreshing its job's heartbeat (``worker.heartbeat``); the executor calls
  ``StartedJobRegistry.cleanup()`` every ``maintenance_seconds`` and RQ re-queues the
  abandoned job (or fails it when its retries are spent).
- A batch whose job fails for good is split into one-genome jobs, so a genome that crashes
  the simulator fails alone; a one-genome job that fails for good becomes that genome's
  failed result (worst fitness, the error kept), never an endless retry.
- Redis restarted or unreachable: the executor waits with back-off and resubmits every job
  Redis forgot; results are taken once per task, so a batch that ran twice changes nothing.
- A job that returns unusable results (not one well-formed result per task:
  ``worker.tasks.result_problem``, or more than ``max_result_bytes`` of JSON) is logged with
  the worker that ran it, deleted and queued again, at most ``MAX_BAD_RESULTS`` times; then
  its genomes get failed results that say why.
"""

from __future__ import annotations

import hashlib
import json
import logging
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

from redis import Redis
from redis.exceptions import RedisError
from rq import Queue, Retry, Worker
from rq.job import Job, JobStatus
from rq.registry import StartedJobRegistry
from rq.results import Result
from rq.serializers import JSONSerializer
from rq.worker_registration import clean_worker_registry

from softevo import __version__
from softevo.service.runs.executors import ResultJSON, TaskJSON, chunks
from softevo.service.settings import GENOMES_PER_TASK, Settings
from softevo.worker.rq_worker import JOB_FUNCTION, VERSION_KEY, EvaluationJob, done_stream
from softevo.worker.tasks import failed, result_problem

WAITING = {
    JobStatus.QUEUED.value,
    JobStatus.STARTED.value,
    JobStatus.DEFERRED.value,
    JobStatus.SCHEDULED.value,
    JobStatus.CREATED.value,
    JobStatus.READY_TO_ENQUEUE.value,
    JobStatus.RATE_LIMITED.value,
}
MAX_BAD_RESULTS = 3  # resubmits of a batch whose job "finished" without usable results
def setting_default(name: str):
    """The default of a ``service.settings.Settings`` field: the one place each is written."""
    return Settings.model_fields[name].default


MAX_RESULT_BYTES = setting_default("max_result_bytes")  # JSON of one job's results, at most
GATHER_SECONDS = 0.02  # once a result arrived, how long a poll waits for the ones close behind
SWEPT = 500  # jobs whose statuses a sweep reads per maintenance period, at most, on average

log = logging.getLogger(__name__)


class ExecutorStopped(RuntimeError):
    """Raised by ``evaluate`` when the executor is asked to stop while it waits."""


@dataclass
class Ticket:
    """One ``submit``'s tasks, their results as they come (None: not yet) and the jobs still
    waiting for theirs."""

    tasks: list[TaskJSON]
    results: list[ResultJSON | None]
    waiting: dict[str, JobBatch] = field(default_factory=dict)

    @property
    def done(self) -> bool:
        return not self.waiting


@dataclass
class JobBatch:
    """One job: its id, its tasks and where their results go in the caller's list."""

    job_id: str
    tasks: list[TaskJSON]
    positions: list[int]
    single: bool = False
    bad_results: int = field(default=0)


def batch_digest(tasks: list[TaskJSON]) -> str:
    """Short hash of a batch's tasks (canonical JSON): equal batches, equal job ids."""
    text = json.dumps(tasks, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:10]


def job_id_of(tasks: list[TaskJSON], index: int) -> str:
    """``run<r>-gen<g>-batch<index>-<digest>`` (``batch<index>-<digest>`` without run info).

    RQ job ids may hold letters, digits, ``_`` and ``-`` only.
    """
    head = tasks[0]
    run_id, generation = head.get("run_id"), head.get("generation")
    prefix = ""
    if isinstance(run_id, int) and isinstance(generation, int):
        prefix = f"run{run_id}-gen{generation}-"
    return f"{prefix}batch{index}-{batch_digest(tasks)}"


def plan_batches(
    tasks: list[TaskJSON], workers: int, genomes_per_job: int, across_runs: bool = False
) -> list[JobBatch]:
    """Split ``tasks`` into jobs: per (run, generation), at most ``genomes_per_job`` each and at
    least one per worker (as the local executor does). ``across_runs``: one group for all the
    runs' tasks of the round, so a job can be one large batch (GPU workers, docs/cluster.md)."""
    groups: dict[tuple[Any, Any], list[int]] = {}
    for position, task in enumerate(tasks):
        key = (None, None) if across_runs else (task.get("run_id"), task.get("generation"))
        groups.setdefault(key, []).append(position)
    batches = []
    for positions in groups.values():
        for index, part in enumerate(chunks(positions, max(1, workers), genomes_per_job)):
            batch_tasks = [tasks[p] for p in part]
            batches.append(JobBatch(job_id_of(batch_tasks, index), batch_tasks, list(part)))
    return batches


def failed_result(task: TaskJSON, error: str) -> dict[str, Any]:
    """The JSON result of a genome whose job failed for good (``worker.tasks.failed``)."""

    return failed({"id": task.get("id")}, error).to_json()


def connect(redis_url: str) -> Redis:
    """A Redis client with timeouts (a dead server raises instead of hanging forever)."""
    return Redis.from_url(redis_url, socket_timeout=30, socket_connect_timeout=5, health_check_interval=15)


class RQExecutor:
    """Evaluates tasks as RQ jobs; see the module doc."""

    def __init__(
        self,
        redis_url: str,
        queue: str = setting_default("queue"),
        genomes_per_job: int = GENOMES_PER_TASK,
        job_timeout: int = setting_default("job_timeout"),
        retries: int = setting_default("job_retries"),
        result_ttl: int = setting_default("result_ttl"),
        maintenance_seconds: float = 2.0,
        stop: threading.Event | None = None,
        across_runs: bool = False,
        max_result_bytes: int = MAX_RESULT_BYTES,
    ) -> None:
        self.connection = connect(redis_url)
        # EvaluationJob: RQ's maintenance here imports no function, callback or webhook named
        # in Redis (an abandoned job's failure callback), as on the workers (docs/security.md)
        self.queue = Queue(
            queue, connection=self.connection, serializer=JSONSerializer, job_class=EvaluationJob
        )
        self.genomes_per_job = genomes_per_job
        self.across_runs = across_runs
        self.job_timeout = job_timeout
        self.retries = retries
        self.result_ttl = result_ttl
        self.maintenance_seconds = maintenance_seconds
        self.max_result_bytes = max_result_bytes
        self.stop = stop or threading.Event()
        self._last_maintenance = 0.0
        self._last_sweep = 0.0  # the first poll looks at every job: some may have ended already
        self._done = done_stream(queue)
        self._done_cursor: str | None = None  # the last entry of the done stream read

    # -- the Executor interface -------------------------------------------------------------

    @property
    def pipelined(self) -> bool:
        """Runs go at their own pace, generations in flight, unless a round's genomes are
        batched across runs (GPU workers want the whole round in a few large jobs)."""
        return not self.across_runs

    def drop_runs(self, run_ids: Iterable[int]) -> None:
        """Nothing to drop: queued jobs stay in Redis (a run resumed takes their results by
        their ids), and the coordinator forgets a cancelled run's generation in flight."""

    def keep_runs(self, run_ids: Iterable[int]) -> None:
        """Nothing dropped, nothing to take again."""

    @property
    def workers(self) -> int:
        """RQ workers listening on the queue now (at least 1, for planning and estimates)."""
        try:
            return max(1, self.worker_count())
        except RedisError:
            return 1

    def evaluate(self, tasks: list[TaskJSON]) -> list[ResultJSON]:
        """Results of ``tasks`` in order; blocks until every batch has its results."""
        ticket = self.submit(tasks)
        while not ticket.done:
            self.wait([ticket])
        return ticket.results  # type: ignore[return-value]

    # -- many generations in flight (service.runs.coordinator.Coordinator.advance) ----------------

    def submit(self, tasks: list[TaskJSON]) -> Ticket:
        """Enqueue ``tasks`` (one run's generation) and return at once; ``wait`` fills the
        ticket's results. Tickets of several runs are in flight together, so that workers
        take another run's jobs while one run waits for its slowest evaluation."""
        ticket = Ticket(list(tasks), [None] * len(tasks))
        batches = plan_batches(tasks, self.workers, self.genomes_per_job, self.across_runs) if tasks else []
        ticket.waiting = {b.job_id: b for b in batches}
        self._retrying(lambda: self._submit(batches, replace_failed=True))
        return ticket

    def wait(self, tickets: Iterable[Ticket], timeout: float | None = None) -> list[Ticket]:
        """Wait until one of ``tickets`` has all its results, or ``timeout`` seconds (None:
        as long as it takes); return the tickets that are done."""
        tickets = list(tickets)
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            done = [ticket for ticket in tickets if ticket.done]
            if done or not tickets:
                return done
            if self.stop.is_set():
                raise ExecutorStopped("executor stopped while waiting for results")
            owner = {job_id: t for t in tickets for job_id in t.waiting}
            waiting = {job_id: batch for t in tickets for job_id, batch in t.waiting.items()}
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            settled = self._retrying(partial(self._poll, waiting, left))
            for batch, outcome in settled or []:
                ticket = owner[batch.job_id]
                del ticket.waiting[batch.job_id]
                if isinstance(outcome, list):
                    for position, result in zip(batch.positions, outcome, strict=True):
                        ticket.results[position] = result
                else:
                    ticket.waiting.update(outcome)
            if deadline is not None and time.monotonic() >= deadline:
                return [ticket for ticket in tickets if ticket.done]

    def close(self) -> None:
        """Close the Redis connections."""
        self.connection.close()

    # -- status for /health -----------------------------------------------------------------

    def worker_count(self) -> int:
        """Live RQ workers on the queue (dead ones are dropped from the registry first)."""
        clean_worker_registry(self.queue)
        return Worker.count(queue=self.queue)

    def queued(self) -> int:
        """Jobs waiting in the queue."""
        return self.queue.count

    # -- internals --------------------------------------------------------------------------

    def _retrying(self, action):
        """Run ``action``; while Redis is unreachable, wait (back-off up to 5 s) and retry."""
        delay = 0.2
        while True:
            try:
                return action()
            except RedisError as exc:
                if self.stop.is_set():
                    raise ExecutorStopped("executor stopped while Redis was unreachable") from exc
                log.warning("redis unreachable (%s); retrying in %.1f s", exc, delay)
                self.stop.wait(delay)
                delay = min(5.0, delay * 2)

    def _submit(self, batches: Iterable[JobBatch], replace_failed: bool = False) -> None:
        """Enqueue the batches Redis does not hold yet; leave queued, running and finished jobs
        alone (their results will be taken); replace failed or stopped leftovers if asked."""
        batches = list(batches)
        statuses = self._statuses([b.job_id for b in batches])
        fresh = []
        for batch, status in zip(batches, statuses, strict=True):
            if status in WAITING or status == JobStatus.FINISHED.value:
                continue
            if status is not None and not replace_failed:
                continue
            if status is not None:
                self._delete(batch.job_id)
            fresh.append(batch)
        if fresh:
            self.queue.enqueue_many([self._job_data(b) for b in fresh])

    def _job_data(self, batch: JobBatch):
        return Queue.prepare_data(
            JOB_FUNCTION,
            args=[batch.tasks],
            timeout=self.job_timeout,
            result_ttl=self.result_ttl,
            failure_ttl=max(self.result_ttl, 3600),
            job_id=batch.job_id,
            description=f"evaluate {len(batch.tasks)} genome(s) ({batch.job_id})",
            retry=Retry(max=self.retries),
            meta={VERSION_KEY: __version__},
        )

    def _fetch(self, job_id: str) -> EvaluationJob | None:
        """The job (None: Redis does not hold it), as ``EvaluationJob`` (no callbacks)."""
        return EvaluationJob.fetch_many([job_id], connection=self.connection, serializer=JSONSerializer)[0]

    def _delete(self, job_id: str) -> None:
        job = self._fetch(job_id)
        if job is not None:
            job.delete()

    def _statuses(self, job_ids: list[str]) -> list[str | None]:
        """Each job's status (None for a job Redis does not hold), in one round trip."""
        with self.connection.pipeline(transaction=False) as pipe:
            for job_id in job_ids:
                pipe.hget(Job.key_for(job_id), "status")
            raw = pipe.execute()
        return [None if value is None else value.decode() for value in raw]

    def _wait_for_results(self, waiting: dict[str, JobBatch], timeout: float | None = None) -> set[str]:
        """Block (up to 0.5 s, or ``timeout``) until the queue's done stream names a job;
        return the ids of ``waiting`` it named. Once something arrived it waits
        ``GATHER_SECONDS`` more, so that one poll settles the jobs ending about together.
        One stream, whatever the number of jobs in flight (other coordinators' jobs are
        named there too, and passed over)."""
        if self._done_cursor is None:  # from now: what ended before, the first sweep finds
            last = self.connection.xrevrange(self._done, "+", "-", count=1)
            self._done_cursor = last[0][0].decode() if last else "0-0"
        block = 500 if timeout is None else max(1, min(500, int(timeout * 1000)))
        response = self.connection.xread({self._done: self._done_cursor}, block=block) or []
        if response:
            time.sleep(GATHER_SECONDS)
            response += self.connection.xread({self._done: response[0][1][-1][0]}) or []
        named = set()
        for _, entries in response:
            for entry_id, fields in entries:
                self._done_cursor = entry_id.decode() if isinstance(entry_id, bytes) else entry_id
                named.add(fields[b"job"].decode())
        return named & waiting.keys()

    def _maintain(self) -> None:
        """Re-queue jobs of dead workers now rather than at RQ's 10-minute maintenance."""
        now = time.monotonic()
        if now - self._last_maintenance < self.maintenance_seconds:
            return
        self._last_maintenance = now
        StartedJobRegistry(queue=self.queue, job_class=EvaluationJob).cleanup()

    def _poll(
        self, waiting: dict[str, JobBatch], timeout: float | None = None
    ) -> list[tuple[JobBatch, list[TaskJSON] | dict[str, JobBatch]]]:
        """Wait a little, then settle what finished: (batch, results) for a finished batch,
        (batch, {id: part}) for a batch replaced by one-genome parts. The jobs the done stream
        names are looked at on every poll; every job, for those that failed, were lost or
        were stopped, once per ``maintenance_seconds`` (longer with more than ``SWEPT`` jobs
        in flight, so that sweeping costs about the same whatever their number)."""
        self._maintain()
        wrote = self._wait_for_results(waiting, timeout)
        now = time.monotonic()
        if now - self._last_sweep >= self.maintenance_seconds * max(1.0, len(waiting) / SWEPT):
            self._last_sweep = now
            batches = list(waiting.values())
        else:
            batches = [batch for job_id, batch in waiting.items() if job_id in wrote]  # in order
        statuses = self._statuses([b.job_id for b in batches])
        finished = [b for b, st in zip(batches, statuses, strict=True) if st == JobStatus.FINISHED.value]
        values = dict(zip((b.job_id for b in finished), self._return_values(finished), strict=True))
        settled: list[tuple[JobBatch, list[TaskJSON] | dict[str, JobBatch]]] = []
        lost = []
        for batch, status in zip(batches, statuses, strict=True):
            if status in WAITING:
                continue
            if status is None:
                lost.append(batch)
            elif status == JobStatus.FINISHED.value:
                outcome = self._finished(batch, values[batch.job_id])
                if outcome is None:
                    lost.append(batch)
                else:
                    settled.append((batch, outcome))
            elif status == JobStatus.FAILED.value:
                settled.append((batch, self._failed(batch)))
            else:  # stopped or canceled by someone: run it again
                self._delete(batch.job_id)
                lost.append(batch)
        if lost:
            log.info("resubmitting %d job(s) Redis lost or left unfinished", len(lost))
            self._submit(lost)
        return settled

    def _return_values(self, batches: list[JobBatch]) -> list[Any]:
        """What each batch's job returned (None: no successful result stored), in one round
        trip: the latest entry of each job's RQ result stream."""
        with self.connection.pipeline(transaction=False) as pipe:
            for batch in batches:
                pipe.xrevrange(Result.get_key(batch.job_id), "+", "-", count=1)
            latest = pipe.execute()
        values = []
        for batch, entries in zip(batches, latest, strict=True):
            result = None
            if entries:
                entry_id, payload = entries[0]
                entry_id = entry_id.decode() if isinstance(entry_id, bytes) else entry_id
                result = Result.restore(batch.job_id, entry_id, payload, self.connection, JSONSerializer)
            ok = result is not None and result.type == Result.Type.SUCCESSFUL
            values.append(result.return_value if ok else None)
        return values

    def _finished(self, batch: JobBatch, value: Any) -> list[ResultJSON] | None:
        """The batch's results (``value``, what its job returned), or None (and the job
        deleted) if they are missing or wrong."""
        problem = self._problem(batch, value)
        if problem is None:
            return value
        job = self._fetch(batch.job_id)
        batch.bad_results += 1
        worker = (job.worker_name if job is not None else None) or "(unknown)"
        log.warning(
            "job %s from worker %s returned unusable results: %s (%d of %d)",
            batch.job_id, worker, problem, batch.bad_results, MAX_BAD_RESULTS + 1,
        )  # fmt: skip
        if batch.bad_results > MAX_BAD_RESULTS:
            error = f"job {batch.job_id} returned no usable results: {problem}"
            return [failed_result(task, error) for task in batch.tasks]
        if job is not None:
            job.delete()
        return None

    def _problem(self, batch: JobBatch, value: Any) -> str | None:
        """Why ``value`` is not the batch's results (None: it is)."""
        if value is None:
            return "no result stored"
        if not isinstance(value, list) or len(value) != len(batch.tasks):
            return f"expected a list of {len(batch.tasks)} results, got {type(value).__name__}"
        size = len(json.dumps(value, separators=(",", ":"), default=str))
        if size > self.max_result_bytes:
            return f"{size} bytes of results, more than {self.max_result_bytes} (SOFTEVO_MAX_RESULT_BYTES)"
        for task, result in zip(batch.tasks, value, strict=True):
            problem = result_problem(result, task["id"])
            if problem:
                return problem
        return None

    def _failed(self, batch: JobBatch) -> list[ResultJSON] | dict[str, JobBatch]:
        """A job that failed for good: split it into one-genome jobs, or fail its genome."""
        if len(batch.tasks) == 1:
            job = self._fetch(batch.job_id)
            reason = _failure_reason(job)
            return [failed_result(batch.tasks[0], f"evaluation job failed: {reason}")]
        parts = {}
        for k, (task, position) in enumerate(zip(batch.tasks, batch.positions, strict=True)):
            part = JobBatch(f"{batch.job_id}-g{k}", [task], [position], single=True)
            parts[part.job_id] = part
        log.warning("job %s failed for good; retrying its genomes one by one", batch.job_id)
        self._submit(parts.values(), replace_failed=True)
        return parts


def _failure_reason(job: Job | None) -> str:
    """Last line of the job's latest failure (e.g. 'AbandonedJobError' for a killed worker)."""
    if job is None:
        return "unknown (job expired)"
    try:
        latest = job.latest_result()
    except Exception:  # an unreadable result must not stop the run
        latest = None
    text = (latest.exc_string if latest is not None else None) or ""
    lines = [line for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else "worker died or the job timed out"
