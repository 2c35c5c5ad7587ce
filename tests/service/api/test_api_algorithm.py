"""A registered algorithm is one registration away from every door: the toy algorithm
(tests/evolution/toy_algorithm.py), registered by a deployment's plugin
(``SOFTEVO_PLUGINS=tests.service.plugin_algorithm``), runs through ``softevo run
--algorithm toy`` and through an experiment POSTed to ``softevo serve`` over real HTTP; the
REST schema accepts it only where it is registered."""

from __future__ import annotations

import httpx
import pytest
from pydantic import ValidationError
from sqlalchemy import create_engine, select

from softevo.service.api.schemas import TreatmentIn
from softevo.service.storage.models import RunRow, TreatmentRow
from tests.evolution.toy_algorithm import NAME, register_toy
from tests.service.rq_support import REPO, Processes, auth, service_env, wait_for
from tests.support import softevo_process

PLUGIN = {"SOFTEVO_PLUGINS": "tests.service.plugin_algorithm", "PYTHONPATH": str(REPO)}
SMALL = {"environment": "land", "stiffness_mpa": 1.0, "population": 3, "generations": 2,
         "workspace": [3, 3, 3], "cycles": 1}


def stored(url: str) -> tuple[list[str], list[tuple[str, int]]]:
    """(each treatment's algorithm, each run's (status, generation)) of a database."""
    engine = create_engine(url)
    with engine.connect() as conn:
        settings = conn.execute(select(TreatmentRow.__table__.c.settings)).scalars().all()
        algorithms = [s["algorithm"] for s in settings]
        runs = conn.execute(select(RunRow.__table__.c.status, RunRow.__table__.c.generation)).all()
    engine.dispose()
    return algorithms, [(str(status), int(generation)) for status, generation in runs]


def test_the_rest_schema_offers_an_algorithm_once_it_is_registered():
    with pytest.raises(ValidationError, match="must be one of afpo, pareto, map-elites"):
        TreatmentIn(**SMALL, algorithm=NAME)
    with register_toy():
        assert TreatmentIn(**SMALL, algorithm=NAME).algorithm == NAME
        enum = TreatmentIn.model_json_schema()["properties"]["algorithm"]["enum"]
        assert enum == ["afpo", "pareto", "map-elites", NAME]


def test_softevo_run_runs_a_plugins_algorithm(tmp_path):
    url = f"sqlite:///{tmp_path / 'toy.db'}"
    options = ["run", "--env", "land", "--stiffness", "1", "--population", "3", "--generations", "2",
               "--workspace", "3,3,3", "--cycles", "1", "--algorithm", NAME, "--db", url]
    done = softevo_process(*options, env=PLUGIN, cwd=REPO)
    assert done.returncode == 0, done.stderr
    algorithms, runs = stored(url)
    assert algorithms == [NAME] and [status for status, _ in runs] == ["finished"]
    unknown = softevo_process(*options, cwd=REPO)  # the plugin not loaded: one line, status 2
    assert unknown.returncode == 2 and unknown.stderr.count("\n") == 1
    assert "unknown algorithm 'toy'; choose one of afpo, pareto, map-elites" in unknown.stderr


@pytest.mark.slow
def test_an_experiment_posted_with_a_plugins_algorithm_runs_to_the_end(tmp_path):
    url = f"sqlite:///{tmp_path / 'served.db'}"
    group = Processes(tmp_path, service_env(url, None, SOFTEVO_WORKERS="1", **PLUGIN))
    try:
        _, base = group.serve()
        body = {"name": "toy", "treatments": [{**SMALL, "name": "toy", "algorithm": NAME}]}
        created = httpx.post(f"{base}/experiments", json=body, headers=auth())
        assert created.status_code == 201, created.text
        (run_id,) = created.json()["runs"]
        wait_for(lambda: httpx.get(f"{base}/runs/{run_id}").json()["status"] == "finished", 120,
                 "the toy run to finish")
        run = httpx.get(f"{base}/runs/{run_id}").json()
        assert run["treatment"]["settings"]["algorithm"] == NAME and run["generation"] == 1
        wrong = httpx.post(f"{base}/experiments", json={"name": "bad", "treatments": [
            {**SMALL, "algorithm": "nope"}]}, headers=auth())
        assert wrong.status_code == 422 and "toy" in wrong.text  # the choices name the plugin's
    finally:
        group.stop_all()
    algorithms, runs = stored(url)
    assert algorithms == [NAME] and runs == [("finished", 1)]
