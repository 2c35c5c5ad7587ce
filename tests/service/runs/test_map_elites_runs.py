"""Acceptance of MAP-Elites on the coordinator (issue 58): a run SIGKILLed mid-run and resumed
stores exactly what an undisturbed one stores, an RQ run whose worker is SIGKILLed in the
middle of a job completes with the archive of an in-process run, and the archive after each
generation, replayed from the stored evaluations (``evolution.archive.current`` and
``elites``, as the views compute it), is the population the algorithm kept."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from sqlalchemy import select

from softevo.evolution.archive import Candidate, current, elites
from softevo.evolution.treatments import Treatment
from softevo.service.runs.coordinator import Coordinator
from softevo.service.runs.rq_executor import RQExecutor
from softevo.service.storage import open_database
from softevo.service.storage.models import EvaluationRow, IndividualRow, PopulationMemberRow
from tests.service import tinyrun
from tests.service.rq_support import Processes, redis_for_test, wait_for

ROOT = Path(__file__).resolve().parents[3]

# land for generations 0-1, water from 2: the archive starts afresh in water
MAP_ELITES = Treatment("land-water", 0.1, name="tiny map-elites", algorithm="map-elites", population=5,
                       generations=4, switch_at=2, workspace=(4, 4, 4), cycles=2, seed=11,
                       measures=("frequency", "voxel_count"), cells=(4, 4))


def stored_archives(engine, run_id: int, treatment: Treatment = MAP_ELITES) -> dict[int, list[tuple]]:
    """{generation: [(cell, local id, distance), ...]} replayed from the stored evaluations,
    in the order the algorithm inserts them (generation, then local id)."""
    grid = treatment.grid()
    ev, ind = EvaluationRow.__table__, IndividualRow.__table__
    with engine.connect() as conn:
        rows = conn.execute(
            select(ev.c.generation, ind.c.local_id, ev.c.environment, ev.c.distance,
                   *(ev.c[name] for name in grid.measures))
            .join(ind, ev.c.individual_id == ind.c.id).where(ev.c.run_id == run_id)
            .order_by(ev.c.generation, ind.c.local_id)
        ).all()
    candidates = [Candidate(row[1], row[3], dict(zip(grid.measures, row[4:], strict=True)), row[0])
                  for row in rows]
    worlds = {row[0]: row[2] for row in rows}
    return {generation: sorted((cell, e.individual, e.distance)
                               for cell, e in elites(grid, current(candidates, worlds, generation)).items())
            for generation in sorted(worlds)}


def stored_populations(engine, run_id: int) -> dict[int, list[int]]:
    pm, ind = PopulationMemberRow.__table__, IndividualRow.__table__
    with engine.connect() as conn:
        rows = conn.execute(select(pm.c.generation, ind.c.local_id).join(ind, pm.c.individual_id == ind.c.id)
                            .where(pm.c.run_id == run_id)).all()
    populations: dict[int, list[int]] = {}
    for generation, local_id in rows:
        populations.setdefault(generation, []).append(local_id)
    return {generation: sorted(ids) for generation, ids in populations.items()}


def check_archives(engine, run_id: int) -> dict[int, list[tuple]]:
    """The replayed archives, each generation's elites its stored population."""
    archives = stored_archives(engine, run_id)
    assert sorted(archives) == list(range(MAP_ELITES.generations))
    populations = stored_populations(engine, run_id)
    for generation, archive in archives.items():
        assert populations[generation] == sorted(local_id for _, local_id, _ in archive)
    assert max(len(archive) for archive in archives.values()) > MAP_ELITES.population
    return archives


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The undisturbed run (SQLite): its snapshot and its archives."""
    folder = tmp_path_factory.mktemp("map-elites")
    engine = open_database(f"sqlite:///{folder / 'ref.db'}")
    run_id = tinyrun.new_run(engine, MAP_ELITES)
    tinyrun.run_to_end(engine, run_id)
    result = tinyrun.snapshot(engine, run_id), check_archives(engine, run_id)
    engine.dispose()
    return result


@pytest.mark.parametrize(("mode", "generation"), [("after-commit", 1), ("during-write", 2)])
def test_sigkill_then_resume_is_identical(engine, db_url, reference, mode, generation):
    assert tinyrun.new_run(engine, MAP_ELITES) == 1
    command = [sys.executable, "-m", "tests.service.killed_run", db_url, mode, str(generation)]
    process = subprocess.Popen(command, cwd=ROOT, stderr=subprocess.PIPE)
    _, stderr = process.communicate(timeout=300)
    assert process.returncode == -signal.SIGKILL, stderr.decode()[-2000:]
    tinyrun.run_to_end(engine, 1)
    snapshot, archives = reference
    assert tinyrun.snapshot(engine, 1) == snapshot
    assert check_archives(engine, 1) == archives


@pytest.mark.redis
@pytest.mark.slow
def test_an_rq_run_with_a_killed_worker_has_the_local_runs_archive(tmp_path):
    """Two ``softevo worker`` processes; one is SIGKILLed while it runs a job of the run's
    first generation; the coordinator (RQ executor, this process) re-queues it and the run
    ends with the archive and every stored row of the in-process run."""
    from redis import Redis
    from rq.job import Job
    from rq.registry import StartedJobRegistry

    treatment = MAP_ELITES.replace(cycles=12, generations=3, switch_at=None, environment="land")
    local = open_database(f"sqlite:///{tmp_path / 'local.db'}")
    local_id = tinyrun.new_run(local, treatment)
    tinyrun.run_to_end(local, local_id)

    engine = open_database(f"sqlite:///{tmp_path / 'rq.db'}")
    run_id = tinyrun.new_run(engine, treatment)
    with redis_for_test() as redis_url:
        queue = "test-map-elites"
        group = Processes(tmp_path, {"SOFTEVO_REDIS_URL": redis_url, "SOFTEVO_QUEUE": queue,
                                     "SOFTEVO_HEARTBEAT_TTL": "3"})
        workers = {name: group.worker(name) for name in ("w1", "w2")}
        executor = RQExecutor(redis_url, queue=queue, genomes_per_job=1, retries=2)
        failure: list[BaseException] = []

        def drive() -> None:
            try:
                Coordinator(engine, executor).run([run_id])
            except BaseException as exc:  # noqa: BLE001 - reported by the test
                failure.append(exc)

        try:
            wait_for(lambda: executor.worker_count() == 2, 90, "two workers to register")
            driver = threading.Thread(target=drive)
            driver.start()
            connection = Redis.from_url(redis_url)
            registry = StartedJobRegistry(queue, connection=connection)

            def w1_job():
                for job_id in registry.get_job_ids(cleanup=False):
                    job = Job.fetch(job_id, connection=connection)
                    if job.worker_name == "w1" and job.get_status() == "started":
                        return job_id
                return None

            killed = wait_for(w1_job, 120, "w1 to start a job", every=0.005)
            workers["w1"].send_signal(signal.SIGKILL)
            workers["w1"].wait(5)
            driver.join(300)
            assert not driver.is_alive() and not failure, failure or group.logs()
            assert Job.fetch(killed, connection=connection).worker_name == "w2"
        finally:
            executor.close()
            group.stop_all()
    assert tinyrun.snapshot(engine, run_id) == tinyrun.snapshot(local, local_id)
    assert stored_archives(engine, run_id, treatment) == stored_archives(local, local_id, treatment)
    assert stored_populations(engine, run_id) == stored_populations(local, local_id)
    engine.dispose()
    local.dispose()
