"""The paper presets through the command line and REST: ``--algorithm`` and ``--model`` (CLI)
or ``algorithm`` and ``model`` (REST, over real HTTP on loopback, coordinator off) choose
other than the paper's; the guard in seconds bounds an evaluation's cost (the limits). The
presets themselves: tests/evolution/test_presets.py."""

from __future__ import annotations

import dataclasses

import httpx
import pytest

from softevo.evolution.treatments import preset_grid
from softevo.service.runs.limits import evaluation_steps
from softevo.service.storage import open_database
from tests.service.rq_support import Processes, auth, service_env
from tests.support import softevo


def test_cli_experiment_takes_algorithm_and_model(capsys, tmp_path):
    db = f"sqlite:///{tmp_path / 'x.db'}"
    code, _, err = softevo(capsys, "experiment", "paper", "--algorithm", "afpo", "--db", db,
                           "--workers", "0", "--quiet", "--repetitions", "1", "--scale", "tiny",
                           "--model", "nope")
    assert code == 2 and "unknown model 'nope'" in err
    code, _, err = softevo(capsys, "experiment", "paper", "--algorithm", "genetic", "--db", db)
    assert code == 2 and "unknown algorithm 'genetic'" in err
    code, _, err = softevo(capsys, "run", "--env", "land", "--stiffness", "1", "--model", "nope",
                           "--db", db)
    assert code == 2 and "unknown model" in err


def test_the_guard_in_seconds_bounds_the_cost_of_the_evosoro_mapping():
    """The evosoro mapping has no lowest frequency: the presets' guard bounds the cost."""
    treatment = preset_grid("paper", "tiny")[5]  # water S1
    tighter = dataclasses.replace(treatment, max_seconds=treatment.max_seconds / 10)
    assert evaluation_steps(tighter) < evaluation_steps(treatment)


def test_cli_run_takes_max_seconds(capsys, tmp_path):
    db = f"sqlite:///{tmp_path / 'x.db'}"
    code, _, err = softevo(capsys, "run", "--env", "land", "--stiffness", "1", "--max-seconds", "0",
                           "--db", db)
    assert code == 2 and err.startswith("error: max_seconds must be") and err.count("\n") == 1


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp("presets")
    url = f"sqlite:///{tmp_path / 'presets.db'}"
    open_database(url).dispose()
    group = Processes(tmp_path, service_env(url, None, SOFTEVO_COORDINATOR="false"))
    _, base = group.serve()
    yield base
    group.stop_all()


def settings_of(base: str, run_id: int) -> dict:
    return httpx.get(f"{base}/runs/{run_id}").json()["treatment"]["settings"]


def test_rest_presets_and_treatments_take_algorithm_and_model(server):
    created = httpx.post(f"{server}/experiments", json={"preset": "paper"}, headers=auth())
    assert created.status_code == 201, created.text
    settings = settings_of(server, created.json()["runs"][0])
    assert (settings["algorithm"], settings["model"]) == ("pareto", "voxcad-land-water")
    assert (settings["control_mapping"], settings["body_rule"]) == ("evosoro-logistic", "evosoro")
    body = {"preset": "gradual", "algorithm": "afpo", "model": "voxelyze-2", "name": "g"}
    created = httpx.post(f"{server}/experiments", json=body, headers=auth())
    settings = settings_of(server, created.json()["runs"][0])
    assert (settings["algorithm"], settings["model"]) == ("afpo", "voxelyze-2")
    treatment = {"environment": "land", "stiffness_mpa": 0.1, "model": "voxcad-land-water",
                 "max_seconds": 2.5}
    created = httpx.post(f"{server}/experiments", json={"name": "t", "treatments": [treatment]},
                         headers=auth())
    settings = settings_of(server, created.json()["runs"][0])
    assert (settings["algorithm"], settings["model"]) == ("afpo", "voxcad-land-water")
    assert settings["max_seconds"] == 2.5


@pytest.mark.parametrize("body", [
    {"name": "t", "treatments": [{"environment": "land", "stiffness_mpa": 0.1, "model": "voxelyze-3"}]},
    {"name": "t", "treatments": [{"environment": "land", "stiffness_mpa": 0.1, "body_rule": "all"}]},
    {"name": "t", "treatments": [{"environment": "land", "stiffness_mpa": 0.1, "max_seconds": 0}]},
    {"preset": "paper", "model": "bullet"},
    {"preset": "paper", "algorithm": "nsga2"},
])
def test_rest_rejects_unknown_models_and_algorithms_with_422(server, body):
    answer = httpx.post(f"{server}/experiments", json=body, headers=auth())
    assert answer.status_code == 422, answer.text


def test_an_experiment_of_some_of_a_presets_treatments_keeps_their_seeds(capsys, tmp_path):
    from softevo.service.reports.data import load_experiment

    db = f"sqlite:///{tmp_path / 'x.db'}"
    picked = ["water S3", "land-water S3"]
    code, _, err = softevo(capsys, "experiment", "paper", "--scale", "tiny", "--algorithm", "afpo",
                           "--treatments", ",".join(picked), "--name", "afpo-variant", "--db", db,
                           "--workers", "0", "--quiet")
    assert code == 0, err
    engine = open_database(db)
    data = load_experiment(engine, 1)
    engine.dispose()
    assert data.experiment["name"] == "afpo-variant" and list(data.treatments["name"]) == picked
    whole = {t.name: t for t in preset_grid("paper", "tiny", algorithm="afpo")}
    assert list(data.treatments["seed"]) == [whole[n].seed for n in picked]
    assert set(data.treatments["algorithm"]) == {"afpo"}
    code, _, err = softevo(capsys, "experiment", "paper", "--treatments", "land S9", "--db", db)
    assert code == 2 and err.startswith("error: no treatment 'land S9' in this preset; it has land S1")
