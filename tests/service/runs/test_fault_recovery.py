"""Faults heal themselves (issue 50): no run is failed by the infrastructure, and the
coordinator loop outlives its own housekeeping's errors. Each fault is injected against a
coordinator loop (``service.runs.driver.CoordinatorLoop``, as ``softevo serve`` runs it) on real
servers on loopback: PostgreSQL (a private cluster), Redis (a private server), real
``softevo worker`` processes, SQLite files; the finished run must equal an undisturbed one
with the same seed (``tinyrun.snapshot``).

- PostgreSQL down while a generation is in flight on RQ workers: the run pauses and goes on
  when the server is back (it was failed with "'NoneType' object is not iterable": the run
  loaded again was told its old self's results).
- SQLite's disk full under ``softevo serve`` with an RQ worker, two runs: both pause and go
  on when space returns (one was failed, as above); and, in-process with local evaluation,
  a database full while two runs store a generation: both pause, said in one line.
- A run cancelled while its generation is in flight, then resumed while the same coordinator
  runs: it finishes (it was failed, or cancelled again after each generation).
- Redis emptied under a coordinator, whose run another coordinator then takes and gives back
  when it stops: the first one finishes it.
- Redis away while the loop drives a run: the loop's thread survives (releasing its locks
  through a dead Redis ended it) and finishes the run once Redis is back.

Each test prints the time from the fault's end to the next stored generation (docs/cluster.md).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import resource
import signal
import subprocess
import sys
import threading
import time
import uuid
from contextlib import contextmanager

import httpx
import pytest
from fastapi.testclient import TestClient
from redis import Redis
from sqlalchemy import event, select

from softevo.evolution.run_status import RunStatus
from softevo.service.api.app import create_app
from softevo.service.runs.driver import CoordinatorLoop
from softevo.service.runs.executors import InlineExecutor, LocalExecutor
from softevo.service.runs.locks import RedisLocks
from softevo.service.runs.rq_executor import RQExecutor
from softevo.service.settings import Settings
from softevo.service.storage import open_database
from softevo.service.storage.advisory_locks import DatabaseLocks
from softevo.service.storage.models import RunRow
from softevo.service.storage.runs import reopen_runs, set_run_status
from tests.service import tinyrun
from tests.service.pg_support import PostgresServer
from tests.service.rq_support import REPO, TOKEN, Processes, RedisServer, auth, service_env, wait_for
from tests.service.runs.test_faults import TINY_BODY

OUTAGE = 3.0  # seconds each outage lasts
POLL = 0.2  # the loops' poll, seconds (serve: 1 s)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The undisturbed run (SQLite, in this process)."""
    return tinyrun.reference_snapshot(tmp_path_factory.mktemp("ref"))


@pytest.fixture
def redis_server():
    server = RedisServer()  # private: a test may stop or empty it
    yield server
    server.stop()


@pytest.fixture
def rq_worker(tmp_path, redis_server):
    """A ``softevo worker`` on a queue of this test: (queue, worker process)."""
    queue = f"test-{uuid.uuid4().hex[:8]}"
    group = Processes(tmp_path, service_env("sqlite://", redis_server.url, SOFTEVO_QUEUE=queue))
    worker = group.worker("w1")
    probe = RQExecutor(redis_server.url, queue=queue)
    wait_for(lambda: probe.worker_count() == 1, 90, "the worker to register")
    probe.close()
    yield queue, worker
    if worker.poll() is None:
        os.kill(worker.pid, signal.SIGCONT)
    group.stop_all()


class Stored:
    """The loop's stored generations as they come: (run, generation, monotonic time)."""

    def __init__(self, loop: CoordinatorLoop) -> None:
        self.rows: list[tuple[int, int, float]] = []
        self._inner = loop.coordinator.on_generation
        loop.coordinator.on_generation = self

    def __call__(self, report) -> None:
        self.rows.append((report.run_id, report.generation, time.monotonic()))
        self._inner(report)

    def first_after(self, moment: float) -> float:
        """Seconds from ``moment`` to the first generation stored after it."""
        return min(t for _, _, t in self.rows if t >= moment) - moment


class FaultAt:
    """Calls ``fault`` once, right after generation ``at``'s tasks are dispatched (the
    generation is then in flight), wrapping an executor's ``submit`` or ``evaluate``."""

    def __init__(self, executor, at: int, fault) -> None:
        self.at, self.fault, self.fired = at, fault, threading.Event()
        name = "submit" if executor.pipelined else "evaluate"  # what the coordinator calls
        inner = getattr(executor, name)

        def wrapped(tasks):
            if self.fired.is_set() or not tasks or tasks[0]["generation"] != self.at:
                return inner(tasks)
            if name == "evaluate":
                self.fired.set()
                self.fault()
                return inner(tasks)
            ticket = inner(tasks)
            self.fired.set()
            self.fault()
            return ticket

        setattr(executor, name, wrapped)


def status_of(engine, run_id: int) -> tuple[str, str | None] | None:
    try:
        with engine.connect() as conn:
            row = conn.execute(
                select(RunRow.__table__.c.status, RunRow.__table__.c.error).where(
                    RunRow.__table__.c.id == run_id
                )
            ).one()
    except Exception:  # the database away
        return None
    return tuple(row)


def generation_of(engine, run_id: int) -> int:
    with engine.connect() as conn:
        return conn.execute(
            select(RunRow.__table__.c.generation).where(RunRow.__table__.c.id == run_id)
        ).scalar_one()


def wait_finished(engine, run_ids, timeout: float = 120) -> None:
    def finished():
        statuses = [status_of(engine, run_id) for run_id in run_ids]
        for run_id, status in zip(run_ids, statuses, strict=True):
            if status is not None and status[0] in ("failed", "cancelled"):
                pytest.fail(f"run {run_id} {status[0]}: {status[1]}")
        return all(status is not None and status[0] == "finished" for status in statuses)

    wait_for(finished, timeout, f"runs {run_ids} to finish", every=0.1)


@contextmanager
def running(loop: CoordinatorLoop):
    loop.start()
    try:
        yield loop
    finally:
        loop.stop()
        loop.executor.close()


def rq_loop(engine, redis_url: str, queue: str, namespace: str = "test", **kwargs) -> CoordinatorLoop:
    """A coordinator loop as ``softevo serve`` with Redis builds it (faster polls)."""
    stop = threading.Event()
    executor = RQExecutor(redis_url, queue=queue, genomes_per_job=2, maintenance_seconds=0.5, stop=stop)
    locks = RedisLocks(redis_url, namespace, ttl=kwargs.pop("ttl", 3.0))
    return CoordinatorLoop(engine, executor, locks, poll_seconds=POLL, stop=stop, **kwargs)


# -- the four outages of issue 50's first item -----------------------------------------------


@pytest.mark.postgres
@pytest.mark.redis
def test_postgres_outage_with_a_generation_in_flight_pauses_the_run(
    rq_worker, redis_server, reference, caplog
):
    queue, worker = rq_worker
    server = PostgresServer()
    try:
        engine = open_database(server.url)
        run_id = tinyrun.new_run(engine)
        loop = rq_loop(engine, redis_server.url, queue, renew_seconds=1.0)
        stored, back = Stored(loop), []

        def outage() -> None:  # the worker held, so that the generation stays in flight
            os.kill(worker.pid, signal.SIGSTOP)
            server.stop()
            threading.Timer(OUTAGE, restore).start()

        def restore() -> None:
            server.start()
            back.append(time.monotonic())
            os.kill(worker.pid, signal.SIGCONT)

        fault = FaultAt(loop.executor, 2, outage)
        caplog.set_level(logging.INFO, logger="softevo.coordinator")
        with running(loop):
            wait_finished(engine, [run_id])
        assert fault.fired.is_set() and back
        print(f"\nPostgreSQL back -> next generation stored: {stored.first_after(back[0]):.2f} s")
        assert "the database cannot be written or reached" in caplog.text
        assert "runs paused" in caplog.text and "go on by themselves" in caplog.text
        assert tinyrun.snapshot(engine, run_id) == reference
        engine.dispose()
    finally:
        server.close()


def test_sqlite_full_while_two_runs_store_pauses_both(tmp_path, reference, caplog):
    url = f"sqlite:///{tmp_path / 'full.db'}"
    engine = open_database(url)
    run_ids = [tinyrun.new_run(engine), tinyrun.new_run(engine)]
    full = threading.Event()

    @event.listens_for(engine, "checkout")
    def pages(dbapi_connection, record, proxy) -> None:  # a full disk: no page may be added
        limit = 1 if full.is_set() else 1_073_741_823  # 1: as many pages as the file has now
        dbapi_connection.execute(f"PRAGMA max_page_count = {limit}")

    back = []

    def outage() -> None:
        full.set()
        threading.Timer(OUTAGE, lambda: (full.clear(), back.append(time.monotonic()))).start()

    loop = CoordinatorLoop(engine, InlineExecutor(), DatabaseLocks(engine), poll_seconds=POLL)
    stored = Stored(loop)
    fault = FaultAt(loop.executor, 2, outage)
    caplog.set_level(logging.INFO, logger="softevo.coordinator")
    with running(loop):
        wait_finished(engine, run_ids)
    assert fault.fired.is_set() and back
    print(f"\nspace back -> next generation stored: {stored.first_after(back[0]):.2f} s")
    assert "database or disk is full" in caplog.text and "runs paused" in caplog.text
    for run_id in run_ids:
        snap = tinyrun.snapshot(engine, run_id)
        assert snap == {**reference, "run": snap["run"]} and snap["run"][:2] == reference["run"][:2]
    engine.dispose()


@pytest.mark.redis
def test_cancel_in_flight_then_resume_under_the_same_coordinator(
    rq_worker, redis_server, tmp_path, reference
):
    queue, worker = rq_worker
    engine = open_database(f"sqlite:///{tmp_path / 'cancel.db'}")
    run_id = tinyrun.new_run(engine)
    loop = rq_loop(engine, redis_server.url, queue)
    stored = Stored(loop)

    def cancel() -> None:  # what POST /runs/{id}/cancel does, its generation 2 in flight
        os.kill(worker.pid, signal.SIGSTOP)
        with engine.begin() as conn:
            set_run_status(
                conn, run_id, RunStatus.CANCELLED, only_from=(RunStatus.PENDING, RunStatus.RUNNING)
            )
        loop.request_cancel(run_id)

    fault = FaultAt(loop.executor, 2, cancel)
    with running(loop):
        wait_for(
            lambda: fault.fired.is_set() and run_id not in loop.locks.held, 60, "the loop to leave the run"
        )
        os.kill(worker.pid, signal.SIGCONT)
        time.sleep(4 * POLL)  # the cancelled generation's jobs end meanwhile
        assert status_of(engine, run_id)[0] == "cancelled"
        with engine.begin() as conn:  # what softevo resume r1 does to the run
            reopen_runs(conn, [run_id])
        resumed = time.monotonic()
        wait_finished(engine, [run_id])
    print(f"\nresumed -> next generation stored: {stored.first_after(resumed):.2f} s")
    assert tinyrun.snapshot(engine, run_id) == reference
    engine.dispose()


@pytest.mark.redis
def test_redis_emptied_and_the_run_handed_back_by_another_coordinator(
    rq_worker, redis_server, tmp_path, reference
):
    """The coordinator's lock lost with an emptied Redis to another coordinator (its locks
    only: the first one's renew may not race it), which later stops: the first one takes
    the run back and finishes it (it was failed, told its old self's generation)."""
    queue, worker = rq_worker
    engine = open_database(f"sqlite:///{tmp_path / 'two.db'}")
    run_id = tinyrun.new_run(engine)
    first = rq_loop(engine, redis_server.url, queue, renew_seconds=1.0)
    other = RedisLocks(redis_server.url, "test", ttl=3.0)  # another coordinator's locks
    stored = Stored(first)
    fault = FaultAt(first.executor, 2, lambda: os.kill(worker.pid, signal.SIGSTOP))
    with running(first):
        wait_for(fault.fired.is_set, 60, "generation 2 in flight")
        Redis.from_url(redis_server.url).flushdb()  # Redis restarted empty ...
        assert other.acquire(run_id)  # ... and the other coordinator took the run
        wait_for(lambda: run_id not in first.locks.held, 30, "the first to see its lock lost")
        wait_for(lambda: not first.active, 30, "the first to leave the run")
        other.release([run_id])  # the other one stopped before it stored anything
        handed = time.monotonic()
        os.kill(worker.pid, signal.SIGCONT)
        wait_finished(engine, [run_id])  # by the first coordinator, which took it back
    print(f"\nhanded back -> next generation stored: {stored.first_after(handed):.2f} s")
    assert tinyrun.snapshot(engine, run_id) == reference
    engine.dispose()


@pytest.mark.redis
def test_a_coordinator_that_lost_its_lock_stores_nothing_more(
    rq_worker, redis_server, tmp_path, reference, caplog
):
    """Redis emptied with a generation in flight; another coordinator takes the run before
    the first one's renew notices: the first stores nothing more (both stored the same
    generations until its renew, harmless only by determinism)."""
    queue, worker = rq_worker
    engine = open_database(f"sqlite:///{tmp_path / 'both.db'}")
    run_id = tinyrun.new_run(engine)
    first = rq_loop(engine, redis_server.url, queue, renew_seconds=30.0, ttl=90.0)  # renews late
    second = rq_loop(engine, redis_server.url, queue, renew_seconds=1.0)
    by_first, by_second = Stored(first), Stored(second)
    fault = FaultAt(first.executor, 2, lambda: os.kill(worker.pid, signal.SIGSTOP))
    caplog.set_level(logging.WARNING, logger="softevo.coordinator")
    with running(first):  # the first takes the run before the second starts (no race for it)
        wait_for(lambda: run_id in first.locks.held, 30, "the first coordinator to take the run")
        with running(second):
            wait_for(fault.fired.is_set, 60, "generation 2 in flight")
            wait_for(lambda: second.waiting, 30, "the second coordinator to wait for the run")
            Redis.from_url(redis_server.url).flushdb()  # Redis restarted empty
            wait_for(lambda: run_id in second.locks.held, 30, "the second coordinator to take the run")
            os.kill(worker.pid, signal.SIGCONT)
            wait_finished(engine, [run_id])
    first_stored = {(run, generation) for run, generation, _ in by_first.rows}
    second_stored = {(run, generation) for run, generation, _ in by_second.rows}
    assert (run_id, 2) in second_stored and not first_stored & second_stored, (first_stored, second_stored)
    assert f"run {run_id} is driven by another coordinator now (its lock was lost)" in caplog.text
    assert tinyrun.snapshot(engine, run_id) == reference
    engine.dispose()


# -- the loop outlives its housekeeping ------------------------------------------------------


@pytest.mark.redis
def test_loop_survives_redis_away_during_its_lock_calls(redis_server, tmp_path, reference, caplog):
    engine = open_database(f"sqlite:///{tmp_path / 'redis.db'}")
    run_id = tinyrun.new_run(engine)
    locks = RedisLocks(redis_server.url, "test", ttl=3.0)
    loop = CoordinatorLoop(engine, InlineExecutor(), locks, poll_seconds=POLL, renew_seconds=1.0)
    stored, back = Stored(loop), []

    def outage() -> None:  # Redis gone before the loop's next lock calls (peers, release)
        redis_server.stop()
        threading.Timer(OUTAGE, lambda: (redis_server.start(), back.append(time.monotonic()))).start()

    FaultAt(loop.executor, 2, outage)
    caplog.set_level(logging.INFO, logger="softevo.coordinator")
    with running(loop):
        wait_for(lambda: back, 30, "Redis to be back")
        assert loop.alive, "the coordinator thread died"
        wait_finished(engine, [run_id])
    print(f"\nRedis back -> next generation stored: {stored.first_after(back[0]):.2f} s")
    assert "Redis cannot be reached" in caplog.text
    assert tinyrun.snapshot(engine, run_id) == reference
    engine.dispose()


def test_a_cancel_is_the_runs_status_and_resume_undoes_it(tmp_path, reference):
    """Local processes (``softevo serve`` without Redis): the run cancelled mid-generation
    and resumed while the same coordinator lives finishes as if never cancelled (it was
    cancelled again after each generation, and its evaluations read as cancelled)."""
    engine = open_database(f"sqlite:///{tmp_path / 'local.db'}")
    run_id = tinyrun.new_run(engine)
    loop = CoordinatorLoop(engine, LocalExecutor(workers=1), DatabaseLocks(engine), poll_seconds=POLL)

    def cancel() -> None:  # what POST /runs/{id}/cancel does
        with engine.begin() as conn:
            set_run_status(conn, run_id, RunStatus.CANCELLED, only_from=(RunStatus.RUNNING,))
        loop.request_cancel(run_id)

    fault = FaultAt(loop.executor, 2, cancel)
    with running(loop):
        wait_for(lambda: fault.fired.is_set() and not loop.active, 60, "the loop to leave the run")
        assert status_of(engine, run_id)[0] == "cancelled"
        with engine.begin() as conn:  # what softevo resume r1 does to the run
            reopen_runs(conn, [run_id])
        wait_finished(engine, [run_id])
    assert tinyrun.snapshot(engine, run_id) == reference
    engine.dispose()


class LosesAResult(InlineExecutor):
    """Answers one task of run ``run_id``'s generation 1 with another id: a bug of that run."""

    def __init__(self, run_id: int) -> None:
        super().__init__()
        self.run_id = run_id

    def evaluate(self, tasks):
        results = super().evaluate(tasks)
        mine = [
            i for i, task in enumerate(tasks) if task["run_id"] == self.run_id and task["generation"] == 1
        ]
        for i in mine[-1:]:
            results[i] = {**results[i], "id": -1}
        return results


def test_a_failed_run_says_why_in_one_line(tmp_path, reference, caplog):
    engine = open_database(f"sqlite:///{tmp_path / 'bug.db'}")
    broken, sound = tinyrun.new_run(engine), tinyrun.new_run(engine)
    loop = CoordinatorLoop(engine, LosesAResult(broken), DatabaseLocks(engine), poll_seconds=POLL)
    caplog.set_level(logging.INFO, logger="softevo.coordinator")
    with running(loop):
        wait_finished(engine, [sound])
    status, error = status_of(engine, broken)
    assert status == "failed"
    assert error.startswith("storing generation 1 failed: KeyError") and "Traceback" not in error, error
    assert "tell" in error and "the traceback is in the coordinator's log" in error, error
    failed = [r for r in caplog.records if r.levelno == logging.ERROR and "failed" in r.getMessage()]
    assert len(failed) == 1 and failed[0].exc_info is not None, [r.getMessage() for r in failed]
    assert failed[0].getMessage() == f"run {broken} failed: {error.split('; the traceback')[0]}"
    assert tinyrun.snapshot(engine, sound) == reference  # the other run went on
    engine.dispose()


def test_softevo_resume_leaves_a_run_to_the_server_that_drives_it(tmp_path):
    """``softevo resume`` takes the run's lock as ``softevo serve`` does: while a server's
    coordinator drives the run it says so in one line and drives nothing (both drove it)."""
    url = f"sqlite:///{tmp_path / 'shared.db'}"
    engine = open_database(url)
    run_id = tinyrun.new_run(engine, dataclasses.replace(tinyrun.TINY, generations=500))
    loop = CoordinatorLoop(engine, InlineExecutor(), DatabaseLocks(engine), poll_seconds=POLL)
    with running(loop):
        wait_for(lambda: generation_of(engine, run_id) >= 0, 60, "the server to drive the run")
        resume = ["resume", f"r{run_id}", "--db", url, "--workers", "0", "-q"]
        done = subprocess.run(
            [sys.executable, "-m", "softevo.service.cli", *resume],
            cwd=REPO, capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert status_of(engine, run_id)[0] == "running" and run_id in loop.locks.held
    assert done.returncode == 0, done.stderr
    assert f"run {run_id} is driven by a softevo serve (the lock file" in done.stderr, done.stderr
    assert f"goes on there by itself; follow it with softevo status r{run_id}" in done.stderr
    engine.dispose()


@pytest.mark.redis
def test_a_restarted_server_takes_its_dead_predecessors_runs_at_once(tmp_path, redis_server):
    """``softevo serve`` SIGKILLed and started again on the same host: the new one takes the
    run at once (it warned "driven by another coordinator" until the dead one's lock expired,
    30 s)."""
    group = Processes(tmp_path, service_env(f"sqlite:///{tmp_path / 'restart.db'}", redis_server.url))

    def log_of(process) -> str:
        return next(path.read_text() for started, path in group.started if started is process)

    try:
        first, base = group.serve()
        body = {"name": "restart", "treatments": [TINY_BODY]}
        (run_id,) = httpx.post(f"{base}/experiments", json=body, headers=auth()).json()["runs"]
        wait_for(lambda: f"driving run {run_id}" in log_of(first), 30, "the first server to drive the run")
        os.killpg(first.pid, signal.SIGKILL)  # no worker: its jobs wait in the queue
        first.wait(10)
        killed = time.monotonic()
        second, _ = group.serve()
        wait_for(lambda: f"driving run {run_id}" in log_of(second), 20, "the second server to take the run")
        print(f"\nserve SIGKILLed -> restarted one drives the run: {time.monotonic() - killed:.2f} s")
        assert "driven by another coordinator" not in log_of(second)
    finally:
        group.stop_all()


# -- /health tells the truth ----------------------------------------------------------------


def test_health_says_when_the_coordinator_loop_has_stopped(tmp_path):
    url = f"sqlite:///{tmp_path / 'health.db'}"
    settings = Settings(db=url, token=TOKEN, workers=0, reports=str(tmp_path / "reports"))
    with TestClient(create_app(settings)) as client:
        assert client.get("/health").json()["status"] == "ok"
        loop = client.app.state.services.loop
        loop.stop_event.set()  # the thread ends as a thread killed by a bug would
        coordinator = next(thread for thread in loop._threads if thread.name == "coordinator")
        coordinator.join(10)
        response = client.get("/health")
    assert response.status_code == 503
    body = response.json()
    assert body["status"] == "degraded" and body["coordinator"] is False
    assert any("coordinator loop has stopped" in reason for reason in body["reasons"]), body


@pytest.mark.redis
def test_health_says_when_jobs_wait_with_no_worker_or_redis_is_away(tmp_path, redis_server):
    env = service_env(f"sqlite:///{tmp_path / 'serve.db'}", redis_server.url)
    group = Processes(tmp_path, env)
    try:
        _, base = group.serve()
        assert httpx.get(f"{base}/health").json()["reasons"] == []
        body = {"name": "waits", "treatments": [{**TINY_BODY}]}
        assert httpx.post(f"{base}/experiments", json=body, headers=auth()).status_code == 201

        def degraded():
            response = httpx.get(f"{base}/health", timeout=5)
            return response.status_code == 503 and response.json()

        health = wait_for(degraded, 30, "/health to say the jobs wait")
        assert health["workers"] == 0 and health["queued"] > 0 and health["coordinator"] is True
        assert health["reasons"] == [
            f"{health['queued']} job(s) wait and no worker is alive: start softevo worker"
        ]
        redis_server.stop()
        health = wait_for(degraded, 30, "/health to say Redis is away")
        assert "Redis cannot be reached" in health["reasons"], health
        redis_server.start()
    finally:
        group.stop_all()


@pytest.mark.redis
def test_serve_without_redis_says_so_once_and_refuses_experiments(tmp_path, redis_server):
    """Issue 49.9: ``softevo serve`` with its Redis away logged a traceback every 5 s and took
    experiments that then stayed pending. Now: one line at start, quiet retries, a 503 for
    a new experiment (nothing stored), and once Redis is back one line and a 201."""
    redis_server.stop()
    env = service_env(f"sqlite:///{tmp_path / 'serve.db'}", redis_server.url)
    group = Processes(tmp_path, env)
    try:
        _, base = group.serve()
        body = {"name": "away", "treatments": [{**TINY_BODY}]}
        refused = httpx.post(f"{base}/experiments", json=body, headers=auth())
        assert refused.status_code == 503 and refused.headers["retry-after"] == "5", refused.text
        assert refused.json()["detail"].startswith("Redis cannot be reached (SOFTEVO_REDIS_URL)")
        assert "it is not stored" in refused.json()["detail"]
        assert httpx.get(f"{base}/experiments").json() == []
        time.sleep(12)  # two more of the loop's retries (every 5 s): said once, not each time
        log = group.logs()
        assert log.count("Redis cannot be reached") == 1 and "Traceback" not in log, log
        redis_server.start()
        wait_for(lambda: "Redis can be reached again" in group.logs(), 60, "the loop to say Redis is back")
        assert httpx.post(f"{base}/experiments", json=body, headers=auth()).status_code == 201
    finally:
        group.stop_all()


@pytest.mark.redis
def test_sqlite_disk_full_under_softevo_serve(rq_worker, redis_server, tmp_path, reference):
    """``softevo serve`` with an RQ worker on a SQLite file, two runs; the server's writes
    refused (``RLIMIT_FSIZE`` of 1 byte: every file it writes is "full") after a stored
    generation, for ``OUTAGE`` seconds: both runs pause, then finish as if undisturbed (one
    was failed: its generation in flight was told to it once loaded again)."""
    queue, _ = rq_worker
    url = f"sqlite:///{tmp_path / 'serve.db'}"
    group = Processes(tmp_path, service_env(url, redis_server.url, SOFTEVO_QUEUE=queue))
    try:
        process, base = group.serve()
        body = {"name": "full", "treatments": [{**TINY_BODY, "name": name} for name in ("a", "b")]}
        created = httpx.post(f"{base}/experiments", json=body, headers=auth())
        assert created.status_code == 201, created.text
        run_ids = created.json()["runs"]
        engine = open_database(url)

        def generation() -> int:
            """The runs' least stored generation (a failed run fails the test)."""
            with engine.connect() as conn:
                rows = conn.execute(select(RunRow.__table__.c.status, RunRow.__table__.c.generation))
                rows = rows.all()
            if any(status == "failed" for status, _ in rows):
                pytest.fail(f"a run failed: {[status_of(engine, run_id) for run_id in run_ids]}")
            return min(generation for _, generation in rows)

        wait_for(lambda: generation() >= 1, 60, "a stored generation")
        resource.prlimit(process.pid, resource.RLIMIT_FSIZE, (1, resource.RLIM_INFINITY))
        stuck = generation()
        time.sleep(OUTAGE)
        assert generation() == stuck, "the server stored a generation on a full disk"
        resource.prlimit(process.pid, resource.RLIMIT_FSIZE, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))
        back = time.monotonic()
        wait_for(lambda: generation() > stuck, 60, "both runs to store a generation once space is back")
        print(
            f"\nspace back -> both runs stored a generation (softevo serve): {time.monotonic() - back:.2f} s"
        )
        wait_finished(engine, run_ids)
    finally:
        group.stop_all()
    for run_id in run_ids:
        snap = tinyrun.snapshot(engine, run_id)
        assert snap == {**reference, "run": snap["run"]} and snap["run"][:2] == reference["run"][:2]
    engine.dispose()


# -- nothing outlives a killed process ------------------------------------------------------


def session_processes(session: int) -> list[int]:
    """Pids of the live processes of ``session`` (Linux's /proc), zombies left out."""
    pids = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as stat:
                fields = stat.read().rsplit(")", 1)[1].split()
        except OSError:  # ended meanwhile
            continue
        if int(fields[3]) == session and fields[0] != "Z":
            pids.append(int(entry))
    return pids


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads Linux's /proc")
def test_evaluator_processes_end_with_a_killed_softevo_run(tmp_path):
    url = f"sqlite:///{tmp_path / 'killed.db'}"
    engine = open_database(url)
    run_id = tinyrun.new_run(engine, dataclasses.replace(tinyrun.TINY, generations=500))
    group = Processes(tmp_path, {})
    parent = group.start("resume", f"r{run_id}", "--db", url, "--workers", "2", "-q", log="resume")
    try:
        # the pool's processes are up once a generation is stored
        wait_for(lambda: generation_of(engine, run_id) >= 0, 120, "a stored generation")
        evaluators = [pid for pid in session_processes(parent.pid) if pid != parent.pid]
        assert len(evaluators) >= 2, evaluators  # two evaluators (and the resource tracker)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(10)
        killed = time.monotonic()
        wait_for(lambda: not session_processes(parent.pid), 15, "the evaluators to end with their parent")
        print(f"\nsoftevo run SIGKILLed -> its evaluators ended: {time.monotonic() - killed:.2f} s")
    finally:
        for pid in session_processes(parent.pid):
            os.kill(pid, signal.SIGKILL)
        group.stop_all()
        engine.dispose()
