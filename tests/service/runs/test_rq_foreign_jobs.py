"""A ``softevo worker`` runs the evaluation job only (issue 30, docs/security.md): jobs that
anyone with write access to Redis can enqueue, naming ``os.system``, a pickled payload,
callbacks or webhooks, with the right ``softevo_version`` in their meta, fail without
running and are logged; a genuine evaluation job on the same queue still runs."""

from __future__ import annotations

import os
import subprocess
import sys
import uuid
from pathlib import Path

import pytest
from redis import Redis
from rq import Callback, Queue
from rq.job import Job
from rq.registry import FailedJobRegistry
from rq.serializers import JSONSerializer, PickleSerializer
from rq.webhook import Webhook

from softevo import __version__
from softevo.service.runs.rq_executor import JOB_FUNCTION as EXECUTOR_FUNCTION
from softevo.worker.rq_worker import JOB_FUNCTION, VERSION_KEY, EvaluationJob, refusal
from tests.service.rq_support import free_port, redis_for_test
from tests.service.runs.test_rq_executor import tasks

pytestmark = pytest.mark.redis
META = {VERSION_KEY: __version__}  # what a forger copies from any genuine job


def touch(*args, **kwargs) -> None:
    """A callback that leaves a mark (the path in ``$SOFTEVO_TEST_MARKER``) if it ever runs."""
    Path(os.environ["SOFTEVO_TEST_MARKER"]).write_text("callback ran")


@pytest.fixture(scope="module")
def redis_url():
    with redis_for_test() as url:
        yield url


def run_burst_worker(redis_url: str, queue: str, marker: Path) -> subprocess.CompletedProcess:
    env = {
        **os.environ,
        "SOFTEVO_REDIS_URL": redis_url,
        "SOFTEVO_QUEUE": queue,
        "SOFTEVO_TEST_MARKER": str(marker),
    }
    return subprocess.run(
        [sys.executable, "-m", "softevo.service.cli", "worker", "--burst", "--name", queue],
        env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip


def test_the_worker_and_the_coordinator_name_the_same_function():
    assert JOB_FUNCTION == EXECUTOR_FUNCTION


def test_a_worker_refuses_foreign_jobs_and_still_runs_the_evaluation_job(redis_url, tmp_path):
    name = f"test-{uuid.uuid4().hex[:8]}"
    connection = Redis.from_url(redis_url)
    rq_queue = Queue(name, connection=connection, serializer=JSONSerializer)
    marker = tmp_path / "pwned"
    pickled_marker = tmp_path / "pwned-by-pickle"
    system = rq_queue.enqueue("os.system", args=[f"id > {marker}"], meta=META, description="evaluate")
    pickled = Queue(name, connection=connection, serializer=PickleSerializer).enqueue(
        os.system, args=[f"id > {pickled_marker}"], meta=META
    )
    with_callbacks = rq_queue.enqueue(
        JOB_FUNCTION,
        args=[tasks(1)],
        meta=META,
        on_success=Callback(f"{__name__}.touch"),
        on_failure=Callback(f"{__name__}.touch"),
    )
    with_webhook = rq_queue.enqueue(
        JOB_FUNCTION,
        args=[tasks(1)],
        meta=META,
        webhooks=[Webhook(f"http://127.0.0.1:{free_port()}/", "failed")],
    )
    genuine = rq_queue.enqueue(JOB_FUNCTION, args=[tasks(2)], meta=META)

    done = run_burst_worker(redis_url, name, marker)
    assert done.returncode == 0, done.stderr[-4000:]

    assert not marker.exists() and not pickled_marker.exists()  # os.system never ran
    refused = [line for line in done.stderr.splitlines() if "refused job" in line]
    assert len(refused) == 4, done.stderr[-4000:]
    foreign = next(line for line in refused if system.id in line)
    assert f"from queue '{name}'" in foreign and "its function is 'os.system'" in foreign
    assert "enqueued at 20" in foreign and "description 'evaluate'" in foreign
    assert any(pickled.id in line and "not RQ's JSON" in line for line in refused)
    assert any(with_callbacks.id in line and "callbacks" in line for line in refused)
    assert any(with_webhook.id in line and "webhooks" in line for line in refused)

    failed = FailedJobRegistry(name, connection=connection, serializer=JSONSerializer)
    for job in (system, with_callbacks, with_webhook):
        stored = Job.fetch(job.id, connection=connection, serializer=JSONSerializer)
        assert stored.get_status() == "failed"
        assert stored.latest_result().exc_string.startswith("RefusedJob: ")
        assert job.id in failed
    assert pickled.id in failed
    assert connection.hget(Job.key_for(pickled.id), "status") == b"failed"

    result = Job.fetch(genuine.id, connection=connection, serializer=JSONSerializer)
    assert result.get_status() == "finished"
    assert [r["id"] for r in result.return_value()] == [0, 1]
    assert all(r["error"] is None for r in result.return_value())
    assert rq_queue.count == 0


def test_the_job_class_imports_nothing_but_the_evaluation_function(redis_url):
    connection = Redis.from_url(redis_url)
    queue = Queue(f"test-{uuid.uuid4().hex[:8]}", connection=connection, serializer=JSONSerializer)
    foreign = queue.enqueue("os.system", args=["true"], on_failure=Callback("os.system"))
    job = EvaluationJob.fetch(foreign.id, connection=connection, serializer=JSONSerializer)
    assert "os.system" in refusal(job)
    with pytest.raises(Exception, match="RefusedJob|os.system") as raised:
        job.func  # noqa: B018 - the property is what RQ calls
    assert type(raised.value).__name__ == "RefusedJob"
    # an abandoned job's failure callback, run by RQ's registry cleanup: never imported
    assert job.failure_callback is None and job.success_callback is None and job.stopped_callback is None
    genuine = queue.enqueue(JOB_FUNCTION, args=[[]], meta=META)
    job = EvaluationJob.fetch(genuine.id, connection=connection, serializer=JSONSerializer)
    assert refusal(job) is None
    from softevo.worker.evaluate import evaluate_batch

    assert job.func is evaluate_batch
