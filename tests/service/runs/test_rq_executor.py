"""The RQ executor and the run locks against a real Redis and a real ``softevo worker``:
same results as in-process evaluation, deterministic job ids, a resubmitted batch is not
evaluated again, a job that fails for good fails only its own genome, one coordinator per
run."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import uuid

import numpy as np
import pytest
from redis import Redis
from rq import Queue
from rq.job import Job
from rq.serializers import JSONSerializer

from softevo import __version__
from softevo.evolution.genotype import EncodingConfig, random_viable_genotype
from softevo.service.runs.executors import InlineExecutor
from softevo.service.runs.locks import RedisLocks
from softevo.service.runs.rq_executor import JOB_FUNCTION, RQExecutor, plan_batches
from softevo.worker.rq_worker import VERSION_KEY
from tests.service.rq_support import Processes, redis_for_test, wait_for

pytestmark = pytest.mark.redis
JOB_ID = re.compile(r"^run(\d+)-gen(\d+)-batch(\d+)-[0-9a-f]{10}$")


def tasks(n: int, run_id: int = 1, generation: int = 0, seed: int = 0) -> list[dict]:
    config = EncodingConfig(workspace=(3, 3, 3))
    rng = np.random.default_rng(seed)
    return [
        {
            "id": k,
            "run_id": run_id,
            "generation": generation,
            "genome": random_viable_genotype(rng, config).to_dict(),
            "environment": "land",
            "youngs_modulus": 1e5,
            "cycles": 1,
            "encoding": config.to_dict(),
        }
        for k in range(n)
    ]


def without_seconds(results: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "seconds"} for r in results]


@pytest.fixture(scope="module")
def redis_url():
    with redis_for_test() as url:
        yield url


@pytest.fixture(scope="module")
def queue(redis_url, tmp_path_factory):
    """A queue with one live ``softevo worker``."""
    name = f"test-{uuid.uuid4().hex[:8]}"
    env = {"SOFTEVO_REDIS_URL": redis_url, "SOFTEVO_QUEUE": name, "SOFTEVO_HEARTBEAT_TTL": "3"}
    group = Processes(tmp_path_factory.mktemp("worker"), env)
    group.worker("executor-test")
    executor = RQExecutor(redis_url, queue=name, genomes_per_job=2, retries=1)
    wait_for(lambda: executor.worker_count() == 1, 60, "the worker to register")
    executor.close()
    yield name
    group.stop_all()


def test_job_ids_name_run_generation_and_batch():
    batches = plan_batches(tasks(3, run_id=4, generation=7) + tasks(2, run_id=5), 2, 2)
    ids = [b.job_id for b in batches]
    parsed = [JOB_ID.match(i).groups() for i in ids]
    assert parsed == [("4", "7", "0"), ("4", "7", "1"), ("5", "0", "0"), ("5", "0", "1")]
    assert [b.positions for b in batches] == [[0, 1], [2], [3], [4]]  # >= 1 job per worker
    again = [b.job_id for b in plan_batches(tasks(3, run_id=4, generation=7) + tasks(2, 5), 2, 2)]
    assert again == ids  # the same batch always has the same id
    other = plan_batches(tasks(3, run_id=4, generation=7, seed=1), 2, 2)
    assert not {b.job_id for b in other} & set(ids)  # other genomes, other jobs


def test_jobs_across_runs_make_one_large_batch_per_round():
    """GPU workers (SOFTEVO_JOBS_ACROSS_RUNS): all runs' genomes of a round in one job, up to
    ``genomes_per_job``; every task once, in its place."""
    work = tasks(3, run_id=4, generation=7) + tasks(2, run_id=5) + tasks(4, run_id=6)
    (batch,) = plan_batches(work, 1, 1000, across_runs=True)
    assert batch.positions == list(range(9)) and batch.tasks == work
    parts = plan_batches(work, 1, 4, across_runs=True)
    assert [b.positions for b in parts] == [[0, 1, 2, 3], [4, 5, 6, 7], [8]]
    assert len({b.job_id for b in parts}) == 3


def test_results_equal_in_process_evaluation(redis_url, queue):
    work = tasks(5)
    executor = RQExecutor(redis_url, queue=queue, genomes_per_job=2)
    try:
        remote = executor.evaluate(work)
    finally:
        executor.close()
    local = InlineExecutor(threads=1).evaluate(work)
    assert without_seconds(remote) == without_seconds(local)
    assert [r["id"] for r in remote] == [0, 1, 2, 3, 4]


def test_a_resubmitted_batch_is_not_evaluated_again(redis_url, queue):
    work = tasks(2, run_id=9, generation=3, seed=5)
    executor = RQExecutor(redis_url, queue=queue, genomes_per_job=2)
    try:
        first = executor.evaluate(work)
        second = executor.evaluate(work)  # e.g. a restarted coordinator asks again
    finally:
        executor.close()
    assert second == first
    (batch,) = plan_batches(work, 1, 2)
    job = Job.fetch(batch.job_id, connection=Redis.from_url(redis_url), serializer=JSONSerializer)
    assert len(job.results()) == 1  # one execution only


def test_a_job_that_fails_for_good_fails_only_its_genome(redis_url, queue):
    work = tasks(2, run_id=11, seed=3)
    del work[1]["id"]  # evaluate_batch cannot even report on this task: the job raises
    executor = RQExecutor(redis_url, queue=queue, genomes_per_job=2, retries=1)
    try:
        results = executor.evaluate(work)
    finally:
        executor.close()
    good = InlineExecutor(threads=1).evaluate(work[:1])
    assert without_seconds(results[:1]) == without_seconds(good)
    assert results[1]["stable"] is False and results[1]["distance"] == 0.0
    assert "evaluation job failed" in results[1]["error"] and "KeyError" in results[1]["error"]


def test_one_coordinator_per_run(redis_url):
    namespace = uuid.uuid4().hex[:8]
    first, second = RedisLocks(redis_url, namespace), RedisLocks(redis_url, namespace)
    assert first.acquire(1) and not second.acquire(1) and second.acquire(2)
    assert first.renew() == set() and first.owner(1) == first.token
    Redis.from_url(redis_url).delete(first.key(1))  # as after a Redis restart
    assert first.renew() == set() and first.owner(1) == first.token  # taken back
    Redis.from_url(redis_url).set(first.key(1), "someone else")
    assert first.renew() == {1}  # lost to another coordinator
    second.release([2])
    assert first.acquire(2)
    first.release([2])
    assert second.owner(2) is None


def test_a_worker_of_another_version_refuses_the_job_and_leaves_it_queued(redis_url, tmp_path):
    name = f"test-{uuid.uuid4().hex[:8]}"
    connection = Redis.from_url(redis_url)
    rq_queue = Queue(name, connection=connection, serializer=JSONSerializer)
    job = rq_queue.enqueue(JOB_FUNCTION, args=[tasks(1)], meta={VERSION_KEY: "0.0.1"})
    env = {**os.environ, "SOFTEVO_REDIS_URL": redis_url, "SOFTEVO_QUEUE": name}
    done = subprocess.run(
        [sys.executable, "-m", "softevo.service.cli", "worker", "--burst", "--name", name],
        env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr[-2000:]
    error_lines = [line for line in done.stderr.splitlines() if line.startswith("error: ")]
    assert len(error_lines) == 1 and "made by softevo 0.0.1" in error_lines[0]
    assert f"this worker runs softevo {__version__}" in error_lines[0]
    assert rq_queue.job_ids == [job.id]  # back in the queue, untouched
    assert Job.fetch(job.id, connection=connection, serializer=JSONSerializer).get_status() == "queued"


def test_tickets_in_flight_return_each_runs_results_as_they_end(redis_url, queue):
    """``submit`` returns at once; ``wait`` hands back the tickets whose jobs all ended, each
    with its results in order, equal to ``evaluate``'s."""
    first, second = tasks(3, run_id=21, seed=8), tasks(2, run_id=22, seed=9)
    executor = RQExecutor(redis_url, queue=queue, genomes_per_job=2)
    try:
        tickets = [executor.submit(first), executor.submit(second)]
        assert not any(ticket.done for ticket in tickets)
        done = []
        while len(done) < 2:
            done += executor.wait([t for t in tickets if t not in done], timeout=30)
        assert executor.wait([executor.submit([])]) != []  # nothing to evaluate: done at once
        again = executor.evaluate(first)
    finally:
        executor.close()
    assert [r["id"] for r in tickets[0].results] == [0, 1, 2]
    assert tickets[0].results == again  # the same jobs: their stored results


def test_runs_driven_at_their_own_pace_store_what_rounds_store(redis_url, queue, tmp_path):
    """The coordinator on the RQ executor advances each run as its generation ends
    (``Coordinator.advance``); two runs of different stiffness store exactly what the same
    runs store when driven in lockstep rounds in-process."""
    from softevo.evolution.treatments import Treatment
    from softevo.service.runs.coordinator import Coordinator
    from softevo.service.runs.submit import create
    from softevo.service.storage import open_database
    from tests.service import tinyrun

    treatments = [
        Treatment("land", 1.0, population=4, generations=3, workspace=(3, 3, 3), cycles=1, seed=5),
        Treatment("water", 0.01, population=4, generations=3, workspace=(3, 3, 3), cycles=1, seed=6),
    ]
    snapshots = []
    for name, make in (("rounds", lambda: InlineExecutor()),
                       ("per-run", lambda: RQExecutor(redis_url, queue=queue, genomes_per_job=2))):
        engine = open_database(f"sqlite:///{tmp_path / name}.db")
        _, run_ids = create(engine, "test", treatments)
        executor = make()
        coordinator = Coordinator(engine, executor)
        assert coordinator.pipelined == (name == "per-run")
        try:
            coordinator.run(run_ids)
        finally:
            executor.close()
        snapshots.append([tinyrun.snapshot(engine, run_id) for run_id in run_ids])
        engine.dispose()
    assert snapshots[0] == snapshots[1]
    assert all(snap["run"][:2] == ("finished", 2) for snap in snapshots[1])


def test_two_coordinators_share_the_runs_and_store_what_one_stores(redis_url, queue, tmp_path):
    """A second coordinator on the same database and Redis takes its share of the runs
    (``ceil(unfinished / coordinators)``): the first hands runs over between generations,
    each drives at most its share once both count each other, and what they store together
    is what one coordinator stores alone."""
    import time

    from softevo.evolution.treatments import Treatment
    from softevo.service.runs.coordinator import Coordinator
    from softevo.service.runs.driver import CoordinatorLoop
    from softevo.service.runs.submit import create
    from softevo.service.storage import open_database
    from tests.service import tinyrun

    treatment = Treatment("land", 1.0, population=4, generations=8, workspace=(3, 3, 3), cycles=1, seed=5,
                          repetitions=4)
    alone = open_database(f"sqlite:///{tmp_path / 'alone'}.db")
    _, run_ids = create(alone, "test", [treatment])
    Coordinator(alone, InlineExecutor()).run(run_ids)
    expected = [tinyrun.snapshot(alone, run_id) for run_id in run_ids]

    engine = open_database(f"sqlite:///{tmp_path / 'shared'}.db")
    _, run_ids = create(engine, "test", [treatment])
    namespace = uuid.uuid4().hex[:8]

    def loop() -> CoordinatorLoop:
        executor = RQExecutor(redis_url, queue=queue, genomes_per_job=2)
        return CoordinatorLoop(engine, executor, RedisLocks(redis_url, namespace), poll_seconds=0.1,
                               renew_seconds=0.5)

    first, second = loop(), loop()
    first.start()
    try:
        wait_for(lambda: len(first.active) == 4, 60, "the first coordinator to claim every run")
        second.start()
        wait_for(lambda: first.share == 2 and second.share == 2, 30, "both coordinators to count each other")
        wait_for(lambda: len(first.active) <= 2, 60, "the first coordinator to hand runs over")
        largest = 0
        deadline = time.monotonic() + 240
        while any(tinyrun.snapshot(engine, r)["run"][0] != "finished" for r in run_ids):
            largest = max(largest, len(first.active), len(second.active))
            assert time.monotonic() < deadline, "the runs did not finish"
            time.sleep(0.05)
    finally:
        first.stop()
        second.stop()
    assert first.driven and second.driven and first.driven | second.driven == set(run_ids)
    assert 0 < largest <= 2
    assert [tinyrun.snapshot(engine, run_id) for run_id in run_ids] == expected
