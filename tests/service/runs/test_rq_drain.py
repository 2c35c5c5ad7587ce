"""Workers stopped as SLURM stops them (``worker.slurm``), against a real Redis and real
``softevo worker`` processes:

- the drain signal (SIGTERM to the worker alone, ``--signal=B:TERM@N`` before a time limit)
  while it runs a job: it finishes that job, takes no other, and exits with status 0;
- the time limit itself, ``scancel`` or preemption (SIGTERM to every process of the worker,
  its heartbeat's included, then SIGKILL while the job still runs): the job goes back to
  the queue and another worker takes it.

Either way the results equal in-process evaluation: nothing lost, nothing counted twice.
"""

from __future__ import annotations

import os
import signal
import time
import uuid

import pytest
from redis import Redis
from rq import Queue
from rq.job import Job

from softevo.service.runs.executors import InlineExecutor
from softevo.service.runs.rq_executor import RQExecutor
from tests.service.rq_support import Processes, job_held_by, redis_for_test, wait_for
from tests.service.runs.test_rq_executor import tasks, without_seconds

pytestmark = [pytest.mark.redis, pytest.mark.slow]
CYCLES = 500  # a job of 2 genomes lasts seconds (100 cycles: 0.9 s, too short): running a second on
KILL_WAIT = 1.0  # seconds from SIGTERM to SIGKILL (SLURM's KillWait, 30 by default)


@pytest.fixture
def cluster(tmp_path):
    """(Redis URL, queue, process group) with one worker ``w1`` registered."""
    with redis_for_test() as url:
        queue = f"test-{uuid.uuid4().hex[:8]}"
        env = {"SOFTEVO_REDIS_URL": url, "SOFTEVO_QUEUE": queue, "SOFTEVO_HEARTBEAT_TTL": "3"}
        group = Processes(tmp_path, env)
        group.worker("w1")
        probe = RQExecutor(url, queue=queue)
        wait_for(lambda: probe.worker_count() == 1, 90, "the worker to register")
        probe.close()
        yield url, queue, group
        group.stop_all()
        print(group.logs())


def long_tasks(n: int) -> list[dict]:
    return [{**task, "cycles": CYCLES} for task in tasks(n, run_id=31, seed=4)]


def evaluated(executor: RQExecutor, ticket, work: list[dict]) -> None:
    """Wait for ``ticket``; its results must equal in-process evaluation's."""
    executor.wait([ticket], timeout=180)
    assert ticket.done
    assert without_seconds(ticket.results) == without_seconds(InlineExecutor(threads=1).evaluate(work))


def test_the_drain_signal_lets_the_job_finish_and_takes_no_other(cluster):
    url, queue, group = cluster
    worker = group.started[0][0]
    work = long_tasks(4)  # two jobs of two genomes, one worker
    executor = RQExecutor(url, queue=queue, genomes_per_job=2, maintenance_seconds=1)
    try:
        ticket = executor.submit(work)
        job_id = wait_for(lambda: job_held_by(url, queue, "w1"), 60, "w1 to start a job", every=0.005)
        worker.send_signal(signal.SIGTERM)
        assert worker.wait(60) == 0
        connection = Redis.from_url(url)
        job = Job.fetch(job_id, connection=connection)
        assert job.get_status() == "finished" and job.worker_name == "w1"
        assert Queue(queue, connection=connection).count == 1  # the other job, untouched
        group.worker("w2")
        evaluated(executor, ticket, work)
    finally:
        executor.close()


def test_a_worker_killed_at_its_time_limit_hands_its_job_back(cluster):
    url, queue, group = cluster
    worker = group.started[0][0]
    work = long_tasks(2)
    executor = RQExecutor(url, queue=queue, genomes_per_job=2, maintenance_seconds=1)
    try:
        ticket = executor.submit(work)
        job_id = wait_for(lambda: job_held_by(url, queue, "w1"), 60, "w1 to start the job", every=0.005)
        os.killpg(worker.pid, signal.SIGTERM)  # the worker and its heartbeat process
        time.sleep(KILL_WAIT)
        assert job_held_by(url, queue, "w1") == job_id, "the job ended before the kill: make it longer"
        os.killpg(worker.pid, signal.SIGKILL)
        worker.wait(10)
        group.worker("w2")
        evaluated(executor, ticket, work)
    finally:
        executor.close()
    job = Job.fetch(job_id, connection=Redis.from_url(url))
    assert job.get_status() == "finished" and job.worker_name == "w2"
