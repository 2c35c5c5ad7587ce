"""``softevo worker --burst`` drains its queue across a coordinator's generations (the queue is
briefly empty between them) and quits once it stays drained; with an unreachable Redis the
worker gives one line and exit status 2 after ``--connect-timeout`` seconds."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
import uuid

import pytest
from redis import Redis
from rq.registry import StartedJobRegistry

from softevo.service.runs.rq_executor import RQExecutor
from softevo.worker.rq_worker import drained, redacted
from tests.service.rq_support import redis_for_test
from tests.service.runs.test_rq_executor import tasks

pytestmark = pytest.mark.redis


@pytest.fixture(scope="module")
def redis_url():
    with redis_for_test() as url:
        yield url


def start_worker(redis_url: str, queue: str, *options: str) -> subprocess.Popen:
    env = {**os.environ, "SOFTEVO_REDIS_URL": redis_url, "SOFTEVO_QUEUE": queue}
    return subprocess.Popen(
        [sys.executable, "-m", "softevo.service.cli", "worker", "--name", queue, *options],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def test_a_burst_worker_serves_every_generation_then_quits(redis_url):
    queue = f"test-{uuid.uuid4().hex[:8]}"
    executor = RQExecutor(redis_url, queue=queue, genomes_per_job=2, retries=1)
    worker = start_worker(redis_url, queue, "--burst", "--idle", "3")
    timer = threading.Timer(240, executor.stop.set)  # a worker that quit early: stop waiting
    timer.start()
    try:
        generations = []
        for generation in range(3):  # a coordinator: results, then breeding, then the next batch
            generations.append(executor.evaluate(tasks(2, generation=generation, seed=generation)))
            time.sleep(1.0)
        assert all(r["error"] is None for results in generations for r in results)
        _, stderr = worker.communicate(timeout=60)
        assert worker.returncode == 0, stderr[-3000:]
        assert "drained" in stderr
    finally:
        timer.cancel()
        executor.close()
        if worker.poll() is None:
            worker.kill()
            worker.wait()


def test_the_queue_is_not_drained_while_one_of_its_jobs_runs(redis_url):
    queue = f"test-{uuid.uuid4().hex[:8]}"
    connection = Redis.from_url(redis_url)
    assert drained(connection, queue)
    registry = StartedJobRegistry(queue, connection=connection)
    connection.zadd(registry.key, {"run1-gen0-batch0-0123456789:execution": time.time() + 600})
    assert not drained(connection, queue)  # its result will make the coordinator queue more
    connection.delete(registry.key)
    connection.zadd(registry.key, {"run1-gen0-batch1-0123456789:execution": time.time() - 60})
    assert drained(connection, queue)  # a dead worker's entry, expired: cleaned up, not waited on
    connection.delete(registry.key)


def test_an_unreachable_redis_is_one_line_and_exit_2_after_a_bounded_wait():
    started = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-m", "softevo.service.cli", "worker", "--connect-timeout", "2",
         "--redis-url", "redis://:secret@127.0.0.1:1/0"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    seconds = time.monotonic() - started
    assert done.returncode == 2, done.stderr[-3000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: cannot reach Redis at redis://:***@127.0.0.1:1/0")
    assert "after 2 s" in lines[0] and "secret" not in done.stderr
    assert 2 <= seconds < 30


def test_a_password_is_hidden():
    assert redacted("redis://:pw@host:6380/0") == "redis://:***@host:6380/0"
    assert redacted("rediss://user:pw@host/0?ssl_ca_certs=x") == "rediss://user:***@host/0?ssl_ca_certs=x"
    assert redacted("redis://host:6379/0") == "redis://host:6379/0"
