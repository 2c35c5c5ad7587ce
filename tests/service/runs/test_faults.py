"""Faults on real servers; in each, no individual is lost or duplicated and the finished run
equals an undisturbed one with the same seed (``tinyrun.snapshot``):

- SQLite's disk full (``RLIMIT_FSIZE`` of the ``softevo resume`` process): one error line,
  exit status 2, the run paused at its last stored generation, the file intact; resumed
  once space returns.
- PostgreSQL (a private cluster) stopped in the middle of a generation and started again:
  the coordinator loop pauses, reconnects, takes its advisory run lock back, and commits
  the generation once.
- Two ``softevo serve`` on one SQLite database: one drives the run, the other logs who holds
  the lock and waits; it takes the run over when the first is SIGKILLed.
- A worker that returns malformed or oversized results: rejected, logged with the worker's
  name, the job queued again. A job that runs past its timeout: retried ``SOFTEVO_JOB_RETRIES``
  times, then its individual is recorded as failed with the timeout as the reason.

(Redis restarted mid-generation: ``test_rq_cluster``.)
"""

from __future__ import annotations

import logging
import os
import resource
import signal
import subprocess
import sys
import threading
import uuid

import httpx
import pytest
from redis import Redis
from sqlalchemy import select, text
from sqlalchemy.exc import OperationalError

from softevo.service.runs.coordinator import Coordinator
from softevo.service.runs.driver import CoordinatorLoop
from softevo.service.runs.executors import InlineExecutor
from softevo.service.runs.rq_executor import RQExecutor
from softevo.service.storage import open_database
from softevo.service.storage.advisory_locks import DatabaseLocks
from softevo.service.storage.models import EvaluationRow, IndividualRow, RunRow
from tests.service import tinyrun
from tests.service.pg_support import PostgresServer
from tests.service.rq_support import REPO, Processes, RedisServer, auth, free_port, service_env, wait_for

FULL_DISK_BYTES = 48 * 1024  # the -shm file's 32 KiB fit, a generation's WAL pages do not
TINY_BODY = {
    "name": "tiny",
    "environment": "land-water",
    "stiffness_mpa": 0.1,
    "population": 4,
    "generations": 5,
    "workspace": [4, 4, 4],
    "cycles": 2,
    "switch_at": 3,
    "seed": 11,
}  # tinyrun.TINY, as the API takes it


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The undisturbed run (SQLite, in this process)."""
    return tinyrun.reference_snapshot(tmp_path_factory.mktemp("ref"))


def _generation(engine, run_id: int = 1) -> int:
    with engine.connect() as conn:
        return conn.execute(
            select(RunRow.__table__.c.generation).where(RunRow.__table__.c.id == run_id)
        ).scalar_one()


def test_sqlite_disk_full_pauses_the_run_and_resume_completes_it(tmp_path, reference):
    url = f"sqlite:///{tmp_path / 'full.db'}"
    engine = open_database(url)
    run_id = tinyrun.new_run(engine)
    Coordinator(engine, InlineExecutor()).run([run_id], max_rounds=2)
    engine.dispose()  # the last connection checkpoints and removes the WAL

    def full_disk() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (FULL_DISK_BYTES, FULL_DISK_BYTES))

    resume = ["resume", f"r{run_id}", "--db", url, "--workers", "0", "-q"]
    done = subprocess.run(
        [sys.executable, "-m", "softevo.service.cli", *resume],
        cwd=REPO, capture_output=True, text=True, timeout=300, preexec_fn=full_disk,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr[-3000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: the database cannot be written"), lines
    assert f"run {run_id} is paused after generation 1" in lines[0] and "softevo resume" in lines[0]
    engine = open_database(url)
    with engine.connect() as conn:
        assert conn.execute(text("PRAGMA integrity_check")).scalar_one() == "ok"
        status = conn.execute(select(RunRow.__table__.c.status)).scalar_one()
    assert _generation(engine, run_id) == 1 and status in ("pending", "running")  # paused, not failed
    tinyrun.run_to_end(engine, run_id)  # space is back
    assert tinyrun.snapshot(engine, run_id) == reference
    engine.dispose()


class StopsPostgresMidGeneration(InlineExecutor):
    """A real inline executor that stops the database while generation ``at`` is evaluated
    (once), and starts it again ``after`` seconds later, when the coordinator has already
    failed to store the generation."""

    def __init__(self, server: PostgresServer, at: int, after: float = 2.0) -> None:
        super().__init__()
        self.server, self.at, self.after = server, at, after
        self.evaluated: list[int] = []
        self.restarted = threading.Event()

    def evaluate(self, tasks):
        results = super().evaluate(tasks)
        generation = tasks[0]["generation"] if tasks else None
        self.evaluated.append(generation)
        if generation == self.at and not self.restarted.is_set():
            self.server.stop()
            threading.Timer(self.after, self._start).start()
        return results

    def _start(self) -> None:
        self.server.start()
        self.restarted.set()


@pytest.mark.postgres
def test_postgres_restarted_mid_generation(reference, caplog):
    server = PostgresServer()
    try:
        engine = open_database(server.url)
        run_id = tinyrun.new_run(engine)
        executor = StopsPostgresMidGeneration(server, at=2)
        locks = DatabaseLocks(engine)
        loop = CoordinatorLoop(engine, executor, locks, poll_seconds=0.2, renew_seconds=0.5)
        caplog.set_level(logging.WARNING, logger="softevo.coordinator")
        loop.start()
        try:
            other = DatabaseLocks(engine)  # a second coordinator on the same database
            wait_for(lambda: run_id in locks.held, 60, "the loop to take the run lock")
            assert not other.acquire(run_id)
            assert "advisory lock" in other.holder(run_id) and "backend pid" in other.holder(run_id)

            def finished():
                try:
                    with engine.connect() as conn:
                        return conn.execute(select(RunRow.__table__.c.status)).scalar_one() == "finished"
                except OperationalError:  # while the server is down
                    return False

            wait_for(finished, 180, "the run to finish after the restart", every=0.2)
        finally:
            loop.stop()
        assert executor.restarted.is_set()
        assert executor.evaluated.count(2) == 2  # generation 2 evaluated again, once
        assert "the database cannot be written or reached" in caplog.text
        assert tinyrun.snapshot(engine, run_id) == reference  # generation 2 committed once
        other.release([run_id])
        engine.dispose()
    finally:
        server.close()


def _serve_two(group: Processes) -> dict:
    """Two ``softevo serve`` started together (their start-ups overlap); process -> URL."""
    ports = [free_port(), free_port()]
    served = {
        group.start("serve", "--port", str(port), log=f"serve-{port}"): f"http://127.0.0.1:{port}"
        for port in ports
    }

    def up():
        for process in served:
            if process.poll() is not None:
                pytest.fail(f"softevo serve exited:\n{group.logs()}")
        return all(httpx.get(f"{base}/health", timeout=2).status_code == 200 for base in served.values())

    wait_for(up, 90, "both softevo serve to answer /health", every=0.25)
    return served


def test_two_coordinators_on_one_database(tmp_path, reference):
    url = f"sqlite:///{tmp_path / 'two.db'}"
    group = Processes(tmp_path, service_env(url, None, SOFTEVO_WORKERS="1"))
    try:
        served = _serve_two(group)  # process -> base URL
        base = next(iter(served.values()))
        body = {"name": "two", "treatments": [TINY_BODY]}
        response = httpx.post(f"{base}/experiments", json=body, headers=auth())
        assert response.status_code == 201, response.text
        (run_id,) = response.json()["runs"]

        def log_of(process) -> str:
            return next(path.read_text() for p, path in group.started if p is process)

        def waiter():
            return next((p for p in served if "is driven by another coordinator" in log_of(p)), None)

        second = wait_for(waiter, 60, "one coordinator to wait for the other")
        (first,) = [p for p in served if p is not second]
        waiting = next(line for line in log_of(second).splitlines() if "another coordinator" in line)
        assert f"run {run_id}" in waiting and f"held by process {first.pid}" in waiting, waiting
        assert f"driving run {run_id}" in log_of(first) and "driving run" not in log_of(second)

        # killed as soon as it drives: a tiny run can finish between two polls of its progress
        os.killpg(first.pid, signal.SIGKILL)  # the second takes the run over
        first.wait(10)

        def finished():
            return httpx.get(f"{served[second]}/runs/{run_id}", timeout=5).json()["status"] == "finished"

        wait_for(finished, 180, "the second coordinator to finish the run", every=0.5)
        assert f"driving run {run_id}" in log_of(second)
    finally:
        group.stop_all()
    engine = open_database(url)
    assert tinyrun.snapshot(engine, run_id) == reference
    engine.dispose()


@pytest.mark.redis
def test_bad_results_are_requeued_and_a_timed_out_job_fails_its_individual(tmp_path, reference, caplog):
    queue = f"test-{uuid.uuid4().hex[:8]}"
    server = RedisServer()  # a private one: nothing shared is flushed
    redis_url = server.url
    try:
        env = {
            **os.environ,
            "SOFTEVO_FAULTY_PLAN": "garbage,oversized,badtype",
            "SOFTEVO_FAULTY_SLOW": "4",  # the last generation: the runs agree until then
            "SOFTEVO_FAULTY_SLEEP": "6",
            "PYTHONUNBUFFERED": "1",
        }
        log_path = tmp_path / "faulty.log"
        with open(log_path, "w") as log:
            worker = subprocess.Popen(
                [sys.executable, "-m", "tests.service.faulty_worker", redis_url, queue, "faulty"],
                cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
            )  # fmt: skip
        executor = RQExecutor(redis_url, queue=queue, genomes_per_job=1, job_timeout=2, retries=1)
        try:
            wait_for(lambda: executor.worker_count() == 1, 90, "the faulty worker to register")
            engine = open_database(f"sqlite:///{tmp_path / 'faulty.db'}")
            run_id = tinyrun.new_run(engine)
            caplog.set_level(logging.WARNING, logger="softevo.service.runs.rq_executor")
            Coordinator(engine, executor).run([run_id])
        finally:
            executor.close()
            worker.send_signal(signal.SIGTERM)
            try:
                worker.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(worker.pid, signal.SIGKILL)
        rejected = [r.getMessage() for r in caplog.records if "unusable results" in r.getMessage()]
        assert len(rejected) == 3 and all("from worker faulty" in m for m in rejected), rejected
        kinds = [("must be a list" in m or "expected a list" in m, "SOFTEVO_MAX_RESULT_BYTES" in m,
                  "distance must be a finite number" in m) for m in rejected]
        assert [sum(column) for column in zip(*kinds, strict=True)] == [1, 1, 1], rejected  # each once

        redis = Redis.from_url(redis_url)
        slow = int(redis.get(f"{queue}:slow"))
        assert int(redis.get(f"{queue}:calls:{slow}:4")) == 2  # the first try and one retry
        snap = tinyrun.snapshot(engine, run_id)
        assert snap["individuals"] == reference["individuals"]  # none lost, none duplicated
        before = [e for e in snap["evaluations"] if e[1] < 4]
        assert before == [e for e in reference["evaluations"] if e[1] < 4]
        last = {e[0]: e for e in snap["evaluations"] if e[1] == 4}
        assert sorted(last) == sorted(e[0] for e in reference["evaluations"] if e[1] == 4)
        timed_out = last[slow]
        assert timed_out[8] is False and "JobTimeoutException" in timed_out[9], timed_out
        assert all(e[9] is None or "Timeout" not in e[9] for k, e in last.items() if k != slow)
        with engine.connect() as conn:
            ev, ind = EvaluationRow.__table__, IndividualRow.__table__
            rows = conn.execute(
                select(ev.c.error).join(ind, ev.c.individual_id == ind.c.id).where(ind.c.local_id == slow)
            ).all()
        assert any(row[0] and "timeout" in row[0].lower() for row in rows)
        engine.dispose()
    finally:
        server.stop()
