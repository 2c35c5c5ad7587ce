"""Issue 30's findings replayed against real servers on loopback (docs/security.md): each test
failed before its fix and asserts the fixed behaviour. Item 1 (workers refuse foreign jobs)
is ``test_rq_foreign_jobs.py``."""

from __future__ import annotations

import http.server
import threading
import uuid

import pytest
from redis import Redis
from rq import Callback, Queue
from rq.job import JobStatus
from rq.registry import StartedJobRegistry
from rq.serializers import JSONSerializer
from rq.webhook import Webhook

from softevo.service.rq_executor import RQExecutor
from softevo.worker.rq_worker import JOB_FUNCTION
from tests.service.rq_support import redis_for_test

CALLED: list[str] = []  # what ``mark`` saw: a callback that ran


def mark(job, *args, **kwargs) -> None:
    """A failure callback that records that it ran (it must never)."""
    CALLED.append(job.id)


class Recorder(http.server.BaseHTTPRequestHandler):
    """A webhook receiver on loopback: records every request it gets."""

    seen: list[str] = []

    def do_POST(self) -> None:  # noqa: N802 - http.server's name
        Recorder.seen.append(self.path)
        self.send_response(200)
        self.end_headers()

    do_GET = do_PUT = do_POST  # noqa: N815

    def log_message(self, *args) -> None:
        pass


@pytest.fixture(scope="module")
def redis_url():
    with redis_for_test() as url:
        yield url


# -- item 1, the coordinator's side: RQ maintenance imports nothing named in Redis --------------


@pytest.mark.redis
def test_the_coordinators_cleanup_calls_no_callback_and_sends_no_webhook(redis_url):
    name = f"test-{uuid.uuid4().hex[:8]}"
    connection = Redis.from_url(redis_url)
    receiver = http.server.HTTPServer(("127.0.0.1", 0), Recorder)
    threading.Thread(target=receiver.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{receiver.server_port}/hook"
    queue = Queue(name, connection=connection, serializer=JSONSerializer)
    job = queue.enqueue(
        JOB_FUNCTION,
        args=[[]],
        on_failure=Callback(f"{__name__}.mark"),
        webhooks=[Webhook(url, "failed")],
    )
    job.set_status(JobStatus.STARTED)  # a worker took it and died: abandoned, expired
    connection.zadd(StartedJobRegistry(queue=queue).key, {f"{job.id}:dead-execution": 1})
    executor = RQExecutor(redis_url, queue=name, maintenance_seconds=0)
    try:
        executor._maintain()
    finally:
        executor.close()
        receiver.shutdown()
    assert connection.hget(f"rq:job:{job.id}", "status") == b"failed"  # cleaned up as before
    assert CALLED == [] and Recorder.seen == []
