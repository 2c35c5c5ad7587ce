"""The distributed service end to end, real components only: Redis, ``softevo serve``
(uvicorn on loopback) and ``softevo worker`` processes, SQLite (and PostgreSQL when
``SOFTEVO_TEST_POSTGRES`` is set).

- An experiment submitted over HTTP with the token completes although one of two workers is
  SIGKILLed in the middle of a job; its results equal an undisturbed in-process run's, and
  the lineage endpoint returns every ancestor down to the root newcomer.
- Redis restarted (empty) under a live coordinator, then the coordinator SIGKILLed: a new
  coordinator resumes the run and reaches the same results.
"""

from __future__ import annotations

import os
import signal

import httpx
import pytest
from redis import Redis
from rq import Queue
from rq.job import Job
from rq.registry import StartedJobRegistry

from softevo.evolution.treatments import Treatment
from softevo.service.runs.coordinator import Coordinator
from softevo.service.runs.executors import InlineExecutor
from softevo.service.runs.submit import create
from softevo.service.storage import open_database
from tests.service import tinyrun
from tests.service.rq_support import (
    Processes,
    RedisServer,
    auth,
    redis_for_test,
    service_env,
    wait_for,
)

pytestmark = [pytest.mark.slow, pytest.mark.redis]

# land -> water at generation 2; cycles make a 2-genome job last long enough to be killed
TREATMENT = {
    "name": "tiny land-water",
    "environment": "land-water",
    "switch_at": 2,
    "stiffness_mpa": 0.1,
    "population": 4,
    "generations": 4,
    "workspace": [4, 4, 4],
    "cycles": 12,
    "seed": 7,
}


@pytest.fixture
def redis_url():
    with redis_for_test() as url:
        yield url


@pytest.fixture
def processes(tmp_path):
    """Start ``softevo`` processes; all are stopped after the test, their logs printed
    (pytest shows them when the test fails)."""
    started: list[Processes] = []

    def make(env):
        group = Processes(tmp_path, env)
        started.append(group)
        return group

    yield make
    for group in started:
        group.stop_all()
        print(group.logs())


def undisturbed(tmp_path, body: dict = TREATMENT) -> dict:
    """The same treatment run in this process, one generation after another."""
    engine = open_database(f"sqlite:///{tmp_path / 'reference.db'}")
    settings = {k: v for k, v in body.items() if k != "workspace"}
    treatment = Treatment(**settings, workspace=tuple(body["workspace"]))
    _, (run_id,) = create(engine, "reference", [treatment])
    Coordinator(engine, InlineExecutor(threads=1)).run([run_id])
    snapshot = tinyrun.snapshot(engine, run_id)
    engine.dispose()
    return snapshot


def submit(base: str, treatment: dict = TREATMENT) -> int:
    body = {"name": "cluster", "treatments": [treatment]}
    assert httpx.post(f"{base}/experiments", json=body).status_code == 401
    response = httpx.post(f"{base}/experiments", json=body, headers=auth())
    assert response.status_code == 201, response.text
    (run_id,) = response.json()["runs"]
    return run_id


def wait_finished(base: str, run_id: int, group: Processes, timeout: float = 240) -> dict:
    def finished():
        run = httpx.get(f"{base}/runs/{run_id}", timeout=5).json()
        if run["status"] in ("failed", "cancelled"):
            pytest.fail(f"run {run_id} {run['status']}: {run['error']}\n{group.logs()}")
        return run if run["status"] == "finished" else None

    return wait_for(finished, timeout, f"run {run_id} to finish", every=0.5)


def kill_mid_job(redis_url: str, queue: str, worker_name: str, process) -> str:
    """SIGKILL ``process`` while it runs a job; return that job's id."""
    connection = Redis.from_url(redis_url)
    registry = StartedJobRegistry(queue, connection=connection)

    def running_job():
        for job_id in registry.get_job_ids(cleanup=False):
            job = Job.fetch(job_id, connection=connection)
            if job.worker_name == worker_name and job.get_status() == "started":
                return job_id
        return None

    job_id = wait_for(running_job, 120, f"{worker_name} to start a job", every=0.005)
    os.kill(process.pid, signal.SIGKILL)
    process.wait(5)
    return job_id


def check_lineage(base: str, individual_id: int) -> list[dict]:
    response = httpx.get(f"{base}/individuals/{individual_id}/lineage")
    assert response.status_code == 200, response.text
    chain = response.json()
    assert chain[0]["id"] == individual_id and chain[0]["depth"] == 0
    for child, parent in zip(chain, chain[1:], strict=False):
        assert child["parent_id"] == parent["id"]
        assert parent["depth"] == child["depth"] + 1
        assert parent["generation_born"] < child["generation_born"]
    assert chain[-1]["parent_id"] is None  # the root newcomer
    return chain


def test_experiment_completes_when_a_worker_is_killed_mid_job(db_url, redis_url, processes, tmp_path):
    env = service_env(db_url, redis_url)
    group = processes(env)
    workers = {name: group.worker(name) for name in ("w1", "w2")}
    _, base = group.serve()
    wait_for(lambda: httpx.get(f"{base}/health").json()["workers"] == 2, 90, "two workers on /health")
    run_id = submit(base)

    killed_job = kill_mid_job(redis_url, env["SOFTEVO_QUEUE"], "w1", workers["w1"])
    run = wait_finished(base, run_id, group)

    job = Job.fetch(killed_job, connection=Redis.from_url(redis_url))
    assert job.get_status() == "finished" and job.worker_name == "w2"
    queue = Queue(env["SOFTEVO_QUEUE"], connection=Redis.from_url(redis_url))
    assert queue.count == 0
    engine = open_database(db_url)
    assert tinyrun.snapshot(engine, run_id) == undisturbed(tmp_path)
    engine.dispose()

    assert run["generation"] == 3 and run["best"] is not None
    chain = check_lineage(base, run["best"]["individual_id"])
    front = httpx.get(f"{base}/runs/{run_id}/front").json()
    assert front["generation"] == 3 and front["individuals"]
    for member in front["individuals"]:
        check_lineage(base, member["id"])
    assert {entry["environment"] for entry in chain} <= {"land", "water"}


def test_redis_restarted_and_coordinator_killed_mid_run(db_url, processes, tmp_path):
    """Redis restarted empty under a live coordinator (jobs, locks and worker registrations
    lost), then the coordinator SIGKILLed and a new one started: the run completes with the
    results of an undisturbed run."""
    # long enough that the generations run while Redis restarts cannot finish it, on an
    # engine of any speed (7 generations once did, when the engine became faster)
    treatment = {**TREATMENT, "generations": 14}
    redis = RedisServer()
    env = service_env(db_url, redis.url)
    group = processes(env)
    try:
        group.worker("w1")
        serve, base = group.serve()
        run_id = submit(base, treatment)

        def generation():
            return httpx.get(f"{base}/runs/{run_id}", timeout=5).json()["generation"]

        wait_for(lambda: generation() >= 1, 120, "generation 1 to be stored")
        redis.stop()
        redis.start()  # empty: no persistence
        reached = generation()
        wait_for(lambda: generation() >= reached + 2, 120, "two more generations after Redis")
        os.killpg(serve.pid, signal.SIGKILL)
        serve.wait(5)
        last = treatment["generations"] - 1
        assert generation_of(db_url, run_id) < last  # unfinished when its coordinator died
        redis.stop()
        redis.start()  # (also drops the dead coordinator's lock, instead of waiting 30 s)
        _, base = group.serve()
        run = wait_finished(base, run_id, group)
        assert run["status"] == "finished"
        engine = open_database(db_url)
        assert tinyrun.snapshot(engine, run_id) == undisturbed(tmp_path, treatment)
        engine.dispose()
    finally:
        group.stop_all()  # while Redis is up: a worker's warm shutdown talks to Redis
        redis.stop()


def generation_of(db_url: str, run_id: int) -> int:
    engine = open_database(db_url)
    try:
        return tinyrun.snapshot(engine, run_id)["run"][1]
    finally:
        engine.dispose()
