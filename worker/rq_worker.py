"""``softevo worker``: an RQ worker that evaluates batches of genomes.

- Jobs and results travel through RQ's JSON serializer (never pickle); the job function is
  ``worker.evaluate.evaluate_batch``, named by the coordinator by its dotted path.
- Only that job runs (docs/security.md). Anyone who can write to Redis can enqueue a job
  naming any function (``os.system``), so the worker checks each job before RQ imports
  anything for it: a job whose function is not ``JOB_FUNCTION``, that names an instance,
  success/failure/stopped callbacks or webhooks, or whose data is not RQ's JSON (a pickled
  job) is refused: logged with its queue, id, function, enqueue time and description,
  marked failed (never retried) and not run. The worker's job class (``EvaluationJob``)
  can import ``JOB_FUNCTION`` alone and no callback at all, also in RQ's own registry
  maintenance.
- The simulator is compiled (or loaded from numba's cache) once, before the first job, and
  jobs run in this process (RQ's ``SimpleWorker``: no fork per job), one numba thread by
  default: run one worker per core.
- A companion process (``worker.heartbeat``) keeps the running job marked alive, so that a
  worker killed mid-job has its job re-dispatched within ``heartbeat_ttl`` seconds.
- Redis unreachable at the start: the worker tries for ``connect_timeout`` seconds, then
  stops with one line (``softevo worker`` exits with status 2). Redis going away later: the
  worker waits and reconnects (under a fresh RQ worker name, since its old registration may
  still be there).
- Each job the worker finishes is named in its queue's done stream (``done_stream``), after
  its result is stored, so that the coordinator learns of it without polling every job.
- Burst (``--burst``): the worker drains its queue and quits once the queue has stayed
  empty, with no job of it running anywhere, for ``idle`` seconds: a coordinator puts the
  next generation's jobs in the queue after the last job of a generation ends, so the
  queue is briefly empty between generations and a worker that quit then would leave the
  run without it.
- Versions: the coordinator stamps each job with its softevo version (job meta
  ``VERSION_KEY``). A worker of another version puts the job back at the front of the queue
  for a worker of the right one, says so in one line and stops (``softevo worker`` exits
  with status 2): its results could differ, and its code may not even read the job.

It needs the Redis URL and nothing else: no database, no HTTP.
"""

from __future__ import annotations

import logging
import os
import signal
import socket
import subprocess
import sys
import time
from urllib.parse import urlsplit, urlunsplit

from redis import Redis
from redis.exceptions import RedisError
from rq.exceptions import DeserializationError, StopRequested
from rq.job import Job
from rq.queue import Queue
from rq.registry import StartedJobRegistry
from rq.serializers import JSONSerializer
from rq.utils import import_attribute, now
from rq.worker import SimpleWorker, WorkerStatus

from softevo import __version__
from softevo.errors import UserError
from softevo.evolution import environments

log = logging.getLogger("softevo.worker")

VERSION_KEY = "softevo_version"  # job meta: the softevo version of the coordinator that made it
JOB_FUNCTION = "softevo.worker.evaluate.evaluate_batch"  # the one function a worker runs
SHOWN = 200  # characters of a refused job's sender-chosen strings that go to the log
CONNECT_TIMEOUT = 5.0  # seconds a starting worker tries to reach Redis (--connect-timeout)
BURST_IDLE = 5  # seconds a burst worker's queue stays empty, nothing running, before it quits
DONE_LENGTH = 100_000  # entries a queue's done stream keeps, about (older ones are trimmed)


def done_stream(queue: str) -> str:
    """The Redis stream in which workers name each job of ``queue`` they have finished
    (succeeded, failed or been given back for a retry), once its result is stored: a
    coordinator reads this one stream instead of watching every job it waits for."""
    return f"softevo:done:{queue}"


class RefusedJob(Exception):
    """A job that is not the evaluation job (``refusal`` says why); it fails without running."""


def _short(value: object) -> str:
    text = repr(value)  # repr: a newline in a sender's string cannot forge a log line
    return text if len(text) <= SHOWN else text[:SHOWN] + "..."


def refusal(job: Job) -> str | None:
    """Why ``job`` must not run (None: it is the evaluation job, with nothing attached).

    Reads the job's decoded data only: nothing is imported or called."""
    try:
        func_name, instance = job.func_name, job.instance
    except (DeserializationError, ValueError, TypeError) as exc:  # pickled, or not RQ's format
        return f"its data is not RQ's JSON (pickled, or another serializer): {type(exc).__name__}"
    if func_name != JOB_FUNCTION:
        return f"its function is {_short(func_name)}, not {JOB_FUNCTION}"
    if instance is not None:
        return f"it calls {JOB_FUNCTION} on an instance ({_short(instance)})"
    callbacks = {
        kind: name
        for kind, name in (
            ("on_success", job._success_callback_name),
            ("on_failure", job._failure_callback_name),
            ("on_stopped", job._stopped_callback_name),
        )
        if name
    }
    if callbacks:
        return f"it has callbacks {_short(callbacks)}; evaluation jobs have none"
    if job.webhooks:
        return f"it has webhooks ({_short([w.url for w in job.webhooks])}); evaluation jobs have none"
    return None


class EvaluationJob(Job):
    """RQ's job that can call ``JOB_FUNCTION`` alone and has no callbacks or webhooks: RQ
    resolves ``func`` and the callbacks by importing the dotted names the sender wrote, here
    and in its registry maintenance (an abandoned job's failure callback and webhooks), on
    the workers and in the coordinator (``service.runs.rq_executor``)."""

    @property
    def func(self):
        problem = refusal(self)
        if problem is not None:
            raise RefusedJob(problem)
        return import_attribute(JOB_FUNCTION)  # the constant, never the sender's string

    @property
    def success_callback(self):
        return None

    @property
    def failure_callback(self):
        return None

    @property
    def stopped_callback(self):
        return None

    def send_webhooks(self, status, *, exc_string=None) -> None:
        """Send nothing: RQ's registry cleanup would POST to the URLs a job's sender wrote."""


class EvaluationWorker(SimpleWorker):
    """RQ's in-process worker, reconnecting to Redis within 5 s of its return, that runs
    only evaluation jobs (any other job fails unrun: ``refuse``) and only those of its own
    softevo version (``refused`` says why it stopped otherwise)."""

    max_connection_wait_time = 5.0
    job_class = EvaluationJob
    refused: str | None = None

    def execute_job(self, job, queue) -> None:
        problem = refusal(job)
        if problem is not None:  # before the version: a foreign job fails whatever it claims
            self.refuse(job, queue, problem)
            return
        made_by = (job.meta or {}).get(VERSION_KEY)
        if made_by != __version__:
            queue.push_job_id(job.id, at_front=True)  # untouched, for a worker of that version
            self.refused = (
                f"refused job {job.id}: it was made by softevo {made_by or '(unknown version)'}, "
                f"this worker runs softevo {__version__}; install the coordinator's version here"
            )
            log.error(self.refused)
            raise StopRequested()
        super().execute_job(job, queue)

    def perform_job(self, job, queue, execution) -> bool:
        problem = refusal(job)  # execute_job has refused it already; no other path runs it
        if problem is not None:
            self._fail_unrun(job, queue, execution, problem)
            return False
        return super().perform_job(job, queue, execution)

    def handle_job_success(self, job, queue, started_job_registry, execution) -> None:
        super().handle_job_success(job, queue, started_job_registry, execution)
        self._say_done(job)

    def handle_job_failure(self, job, queue, started_job_registry=None, exc_string="", execution=None):
        super().handle_job_failure(job, queue, started_job_registry, exc_string, execution)
        self._say_done(job)

    def _say_done(self, job) -> None:
        """Name the job in its queue's done stream (``done_stream``); if Redis refuses, the
        coordinator still finds the job at its next sweep of every job it waits for."""
        try:
            stream = done_stream(job.origin)
            self.connection.xadd(stream, {"job": job.id}, maxlen=DONE_LENGTH, approximate=True)
        except RedisError as exc:
            log.warning("cannot announce job %s as done: %s", _short(job.id), exc)

    def refuse(self, job, queue, problem: str) -> None:
        """Log the refusal with the job's origin, mark the job failed, run nothing."""
        try:
            claimed = (job.meta or {}).get(VERSION_KEY)
        except Exception:  # meta that does not decode
            claimed = None
        log.error(
            "refused job %s from queue %s: %s; enqueued at %s (created %s), description %s, "
            "claims softevo %s; marked failed, not run (docs/security.md)",
            _short(job.id), _short(queue.name), problem,
            job.enqueued_at.isoformat() if job.enqueued_at else "(unknown)",
            job.created_at.isoformat() if job.created_at else "(unknown)",
            _short(job.description), _short(claimed),
        )  # fmt: skip
        execution = self.prepare_execution(job)
        self._fail_unrun(job, queue, execution, problem)
        self.set_state(WorkerStatus.IDLE)

    def _fail_unrun(self, job, queue, execution, problem: str) -> None:
        """RQ's failure bookkeeping (started -> failed registry, a failed result) for a job
        that never ran: no retry, no callback, no webhook."""
        job.retries_left = None
        job.webhooks = []
        try:
            job.func_name  # noqa: B018 - RQ's bookkeeping reads it
        except (DeserializationError, ValueError, TypeError):
            job._func_name = "(undecodable job data)"  # the stored bytes stay as they were
        self.prepare_job_execution(job, remove_from_intermediate_queue=len(self.queues) == 1)
        job.ended_at = now()
        self.handle_job_failure(
            job,
            queue,
            started_job_registry=queue.started_job_registry,
            exc_string=f"{RefusedJob.__name__}: {problem}",
            execution=execution,
        )


def warm(threads: int = 1) -> float:
    """Set numba's threads, compile the simulator and evaluate one random genome (imports the
    descriptor code too); return the seconds it took."""
    import numba
    import numpy as np

    from softevo.evolution.genotype import EncodingConfig, random_viable_genotype
    from softevo.worker.evaluate import ensure_compiled, evaluate_batch, warm_up

    start = time.perf_counter()
    ensure_compiled()  # load the cached kernels, as local pool processes do: same machine code
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    warm_up(threads=threads)
    config = EncodingConfig(workspace=(3, 3, 3))
    genome = random_viable_genotype(np.random.default_rng(0), config)
    task = {
        "id": 0,
        "genome": genome.to_dict(),
        "environment": environments.LAND.name,
        "youngs_modulus": 1e5,
        "cycles": 1,
        "encoding": config.to_dict(),
    }
    evaluate_batch([task], threads=threads)
    return time.perf_counter() - start


def default_name() -> str:
    """``<host>-<pid>``: unique among the workers of a cluster."""
    return f"{socket.gethostname()}-{os.getpid()}"


STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT)  # a worker's stop signals; its heartbeat ignores them


def start_heartbeat(redis_url: str, queue: str, ttl: int) -> subprocess.Popen:
    """The companion heartbeat process (see ``worker.heartbeat``), fed names on its stdin.

    It ignores SIGTERM and SIGINT from its first instruction on (an ignored signal stays
    ignored across fork and exec, so they are ignored here while it starts): those signals
    reach every process of the worker at once (Ctrl-C, ``scancel``, a SLURM time limit), and a
    heartbeat dead of them, even while it imports, would leave the worker's job looking alive
    for the job timeout, or a worker finishing its job looking dead. It ends with the
    worker's pipe."""
    previous = {number: signal.signal(number, signal.SIG_IGN) for number in STOP_SIGNALS}
    try:
        return subprocess.Popen(
            [sys.executable, "-m", "softevo.worker.heartbeat", queue, str(ttl)],
            stdin=subprocess.PIPE,
            text=True,
            env={**os.environ, "SOFTEVO_HEARTBEAT_REDIS": redis_url},
        )
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _announce(heartbeat: subprocess.Popen, name: str) -> None:
    try:
        heartbeat.stdin.write(name + "\n")
        heartbeat.stdin.flush()
    except (BrokenPipeError, OSError):
        log.warning("heartbeat process is gone; a killed job will wait for RQ's own timeout")


def _stop_was_asked(worker: SimpleWorker) -> bool:
    """Whether the worker's loop ended on SIGINT/SIGTERM (RQ keeps that on the worker)."""
    return bool(worker._stop_requested or worker._shutdown_requested_date)


def redacted(redis_url: str) -> str:
    """``redis_url`` with its password (if any) shown as ``***``."""
    parts = urlsplit(redis_url)
    if parts.password is None:
        return redis_url
    host = parts.netloc.rsplit("@", 1)[1]
    user = parts.username or ""
    return urlunsplit(parts._replace(netloc=f"{user}:***@{host}"))


def wait_for_redis(redis_url: str, seconds: float = CONNECT_TIMEOUT) -> None:
    """Return once Redis at ``redis_url`` answers a PING; a UserError (one line) if it has
    not within ``seconds``, or if the URL is not a Redis URL."""
    deadline, delay = time.monotonic() + seconds, 0.2
    while True:
        try:
            timeout = max(0.5, min(5.0, seconds))
            connection = Redis.from_url(redis_url, socket_connect_timeout=timeout, socket_timeout=timeout)
        except ValueError as exc:
            raise UserError(f"not a Redis URL: {redacted(redis_url)} ({exc})") from None
        try:
            connection.ping()
            return
        except RedisError as exc:
            left = deadline - time.monotonic()
            if left <= 0:
                raise UserError(
                    f"cannot reach Redis at {redacted(redis_url)} after {seconds:g} s ({exc}); "
                    "is it running? (--connect-timeout to wait longer)"
                ) from None
        finally:
            connection.close()
        time.sleep(min(delay, left))
        delay = min(1.0, delay * 2)


def drained(connection: Redis, queue: str) -> bool:
    """Whether ``queue`` holds no job and none of its jobs is running on any live worker (so
    no coordinator waits on a result that would make it queue more)."""
    rq_queue = Queue(queue, connection=connection, serializer=JSONSerializer, job_class=EvaluationJob)
    running = StartedJobRegistry(queue=rq_queue, job_class=EvaluationJob)
    running.cleanup()  # a dead worker's job goes back to the queue (or fails), as RQ would
    return rq_queue.count == 0 and running.count == 0


def run_worker(
    redis_url: str,
    queue: str = "softevo",
    name: str | None = None,
    threads: int = 1,
    heartbeat_ttl: int = 30,
    burst: bool = False,
    logging_level: str = "INFO",
    connect_timeout: float = CONNECT_TIMEOUT,
    idle: int = BURST_IDLE,
) -> None:
    """Warm the simulator, then take jobs from ``queue`` until stopped (SIGINT/SIGTERM: the
    running job finishes first) or, with ``burst``, until the queue is drained: empty, with
    none of its jobs running, for ``idle`` seconds. A UserError if Redis does not answer
    within ``connect_timeout`` seconds of the start."""
    logging.basicConfig(level=logging_level, format="%(asctime)s %(name)s %(message)s")
    wait_for_redis(redis_url, connect_timeout)
    heartbeat = start_heartbeat(redis_url, queue, heartbeat_ttl)  # it starts while the simulator warms
    base = worker_name = name or default_name()
    restarts, delay = 0, 1.0
    try:
        seconds = warm(threads)
        log.info("simulator ready in %.1f s (%d numba thread(s))", seconds, threads)
        while True:
            worker = None
            try:
                connection = Redis.from_url(
                    redis_url, socket_timeout=max(20, heartbeat_ttl) + 30, socket_keepalive=True
                )
                worker = EvaluationWorker(
                    [queue],
                    name=worker_name,
                    connection=connection,
                    serializer=JSONSerializer,
                    job_class=EvaluationJob,
                    worker_ttl=max(20, heartbeat_ttl),
                )
                _announce(heartbeat, worker_name)
                worker.work(logging_level=logging_level, max_idle_time=max(1, idle) if burst else None)
                if worker.refused:
                    raise UserError(worker.refused)
                if burst and not _stop_was_asked(worker):
                    if drained(connection, queue):
                        log.info("queue %s drained: no job queued or running for %d s; quitting", queue, idle)
                        return
                    continue  # idle here while another worker's job runs: more may follow
            except RedisError as exc:
                log.warning("redis unreachable (%s); retrying in %.0f s", exc, delay)
            if worker is not None and _stop_was_asked(worker):
                return
            log.warning("worker loop ended (Redis restarted?); starting again")
            time.sleep(delay)
            delay = min(5.0, delay * 2)
            restarts += 1
            worker_name = f"{base}-{restarts}"  # the old registration may still be there
    except (StopRequested, KeyboardInterrupt):
        return
    finally:
        heartbeat.stdin.close()
        heartbeat.wait(timeout=10)
