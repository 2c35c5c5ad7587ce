"""Real servers for the service tests: Redis (a private ``redis-server`` on a free loopback
port, or ``$SOFTEVO_TEST_REDIS_URL``), ``softevo serve`` (uvicorn) and ``softevo worker``
processes, all on 127.0.0.1."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest
from redis import Redis
from redis.exceptions import RedisError

from tests.support import free_port

REPO = Path(__file__).resolve().parents[2]
TOKEN = "test-token-123-456789"  # at least 16 characters (MIN_TOKEN_LENGTH)


def wait_for(condition: Callable[[], object], timeout: float, what: str, every: float = 0.1):
    """Poll ``condition`` until it returns something truthy; fail the test after ``timeout``."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            value = condition()
        except (httpx.HTTPError, OSError, RedisError):
            value = None
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}")
        time.sleep(every)


class RedisServer:
    """A private ``redis-server`` (persistence off) that a test may stop and start again;
    with ``password``, one that refuses clients without it (``requirepass``)."""

    def __init__(self, password: str | None = None) -> None:
        binary = shutil.which("redis-server")
        if binary is None:
            pytest.skip("redis-server is not installed")
        self.binary = binary
        self.port = free_port()
        self.dir = tempfile.mkdtemp(prefix="softevo-redis-")
        self.password = password
        self.process: subprocess.Popen | None = None
        self.start()

    @property
    def url(self) -> str:
        secret = f":{self.password}@" if self.password else ""
        return f"redis://{secret}127.0.0.1:{self.port}/0"

    def start(self) -> None:
        secret = ["--requirepass", self.password] if self.password else []
        self.process = subprocess.Popen(
            [self.binary, "--bind", "127.0.0.1", "--port", str(self.port), "--save", "",
             "--appendonly", "no", "--dir", self.dir, *secret],
            stdout=subprocess.DEVNULL,
        )  # fmt: skip
        wait_for(lambda: Redis.from_url(self.url).ping(), 10, "redis-server to start")

    def stop(self) -> None:
        if self.process is not None:
            self.process.terminate()
            self.process.wait(10)
            self.process = None


def shared_redis_url() -> str | None:
    """``$SOFTEVO_TEST_REDIS_URL`` (set by .ci/run) if that server answers."""
    url = os.environ.get("SOFTEVO_TEST_REDIS_URL")
    if not url:
        return None
    try:
        Redis.from_url(url, socket_connect_timeout=2).ping()
    except Exception:
        return None
    return url


@contextmanager
def redis_for_test() -> Iterator[str]:
    """URL of an empty Redis database: the shared CI server's, else a private server's."""
    url = shared_redis_url()
    if url:
        Redis.from_url(url).flushdb()
        yield url
        return
    server = RedisServer()
    try:
        yield server.url
    finally:
        server.stop()


class Processes:
    """``softevo`` subprocesses of one test, with their logs; all stopped at the end."""

    def __init__(self, tmp_path: Path, env: dict[str, str]) -> None:
        self.tmp_path = tmp_path
        self.env = {**os.environ, **env, "PYTHONUNBUFFERED": "1"}
        self.started: list[tuple[subprocess.Popen, Path]] = []

    def start(self, *args: str, log: str) -> subprocess.Popen:
        path = self.tmp_path / f"{log}.log"
        handle = open(path, "w")  # noqa: SIM115 - closed with the process
        process = subprocess.Popen(
            [sys.executable, "-m", "softevo.service.cli", *args],
            cwd=REPO,
            env=self.env,
            stdout=handle,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        self.started.append((process, path))
        return process

    def serve(self, *extra: str) -> tuple[subprocess.Popen, str]:
        """``softevo serve`` on a free port; returns (process, base URL) once /health answers."""
        port = free_port()
        process = self.start("serve", "--port", str(port), *extra, log=f"serve-{port}")
        base = f"http://127.0.0.1:{port}"

        def up():
            if process.poll() is not None:
                pytest.fail(f"softevo serve exited:\n{self.logs()}")
            return httpx.get(f"{base}/health", timeout=2).status_code in (200, 503)

        wait_for(up, 90, "softevo serve to answer /health", every=0.25)
        return process, base

    def worker(self, name: str) -> subprocess.Popen:
        return self.start("worker", "--name", name, log=f"worker-{name}")

    def logs(self) -> str:
        return "\n".join(f"--- {p.name}\n{p.read_text()[-4000:]}" for _, p in self.started)

    def stop_all(self) -> None:
        for process, _ in self.started:
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
        for process, _ in self.started:
            try:
                process.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(5)


def job_held_by(redis_url: str, queue: str, worker: str) -> str | None:
    """The id of the job ``worker`` runs now on ``queue``, if any."""
    from rq.job import Job
    from rq.registry import StartedJobRegistry

    connection = Redis.from_url(redis_url)
    for job_id in StartedJobRegistry(queue, connection=connection).get_job_ids(cleanup=False):
        job = Job.fetch(job_id, connection=connection)
        if job.worker_name == worker and job.get_status() == "started":
            return job_id
    return None


def service_env(db_url: str, redis_url: str | None, **extra: str) -> dict[str, str]:
    """Environment of a test's serve and worker processes: its own queue, short heartbeats."""
    env = {
        "SOFTEVO_DB": db_url,
        "SOFTEVO_TOKEN": TOKEN,
        "SOFTEVO_QUEUE": f"test-{uuid.uuid4().hex[:8]}",
        "SOFTEVO_HEARTBEAT_TTL": "3",
        "SOFTEVO_GENOMES_PER_JOB": "2",
        "SOFTEVO_REPORTS": str(Path(tempfile.mkdtemp(prefix="softevo-reports-"))),
    }
    if redis_url:
        env["SOFTEVO_REDIS_URL"] = redis_url
    env.update(extra)
    return env


def auth() -> dict[str, str]:
    return {"Authorization": f"Bearer {TOKEN}"}
