"""The notebook API at ``softevo``: each function gives what its layer gives."""

from __future__ import annotations

import re

import numpy as np
import pytest

import softevo
from softevo import sim
from softevo.errors import UserError
from softevo.evolution.descriptors import describe


def test_load_experiment_is_the_stored_experiment(tiny, tiny_data):
    data = softevo.load_experiment(tiny.url, f"e{tiny.experiment_id}")
    assert data.experiment == tiny_data.experiment
    assert data.runs["run_id"].tolist() == tiny_data.runs["run_id"].tolist()
    assert data.generations.equals(tiny_data.generations)
    latest = softevo.load_experiment(tiny.url)  # "latest" by default
    assert latest.experiment["id"] == tiny.experiment_id


def test_load_experiment_reads_every_row_softevo_export_writes(tiny):
    from softevo.service.storage.export import individuals_frame, populations_frame

    data = softevo.load_experiment(tiny.url, f"e{tiny.experiment_id}")
    with tiny.engine.connect() as conn:
        populations = populations_frame(conn, tiny.run_ids)
        evaluations = individuals_frame(conn, tiny.run_ids)
    key = ["run_id", "generation", "individual_id"]
    assert len(data.populations) == len(populations)  # was: generation 0 and the last only
    assert sorted(map(tuple, data.populations[key].to_numpy().tolist())) == sorted(
        map(tuple, populations[key].to_numpy().tolist())
    )
    assert len(data.evaluations) == len(evaluations)  # was: only the kept members' evaluations
    assert data.populations["distance"].notna().all()  # each member with its traits
    part = softevo.load_experiment(tiny.url, f"e{tiny.experiment_id}", generations=[1])
    assert 1 in set(part.populations["generation"]) and len(part.evaluations) < len(data.evaluations)


def test_simulate_and_describe_are_the_layers_functions():
    body = np.array([[[2]], [[1]], [[2]]])
    scene = {"body": body.tolist(), "duration": {"cycles": 1}}
    assert softevo.simulate(scene).distance == sim.simulate(scene).distance
    assert softevo.simulate_many([scene])[0].distance == sim.simulate(scene).distance
    assert softevo.describe(body, 2.0) == describe(body, 2.0)


def test_evolve_runs_in_memory_and_keeps_its_history():
    local = softevo.evolve("water", 0.1, population=4, generations=2, workspace=(3, 3, 3), cycles=1)
    algo = local.evolution
    assert algo.generation == 1 and len(algo.population) == 4
    assert all(ind.evaluated for ind in algo.population)
    assert [row["generation"] for row in local.history] == [0, 1]
    assert local.history[-1]["best_distance"] == max(i.objectives["distance"] for i in algo.population)
    again = softevo.evolve("water", 0.1, population=4, generations=2, workspace=(3, 3, 3), cycles=1)
    assert [i.objectives for i in again.evolution.population] == [i.objectives for i in algo.population]
    assert again.history == local.history
    assert len(repr(local)) < 200 and "generations=2" in repr(local)


def test_evolve_runs_an_abrupt_transition():
    local = softevo.evolve(
        "water-land", 0.1, population=4, generations=3, workspace=(3, 3, 3), cycles=1, switch_at=1
    )
    assert [row["environment"] for row in local.history] == ["water", "land", "land"]
    assert all(row["failed"] < row["survivors"] for row in local.history)  # was: every one failed


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"environment": "moon"}, "unknown environment 'moon'"),
        ({"stiffness_mpa": 100}, "stiffness must be within 0.001..10 MPa (got 100)"),
        ({"population": 1}, "population must be an integer >= 2"),
        ({"workspace": (65, 65, 65)}, "workspace must be 3 integers within 1..64 voxels"),
        ({"environment": "land", "switch_at": 2}, "switch_at needs a transition environment"),
    ],
)
def test_evolve_checks_its_settings_as_the_cli_does(arguments, message):
    with pytest.raises(UserError, match=re.escape(message)):
        softevo.evolve(**{"environment": "water", "generations": 4, **arguments})


@pytest.mark.parametrize("body", ["abc", [[1, 2], [3]], np.zeros((2, 2)), [[[7]]]])
def test_describe_says_what_a_body_is(body):
    """Issue 49.13: ``softevo.describe("abc")`` raised NumPy's UFuncTypeError."""
    with pytest.raises(ValueError, match=re.escape("body must be a 3-D array body[x][y][z] of 0 (empty)")):
        softevo.describe(body)


def test_a_misspelt_objective_is_named():
    """Issue 49.13: ``objectives=("distnace",)`` said "must include distance"."""
    with pytest.raises(UserError, match="unknown objective 'distnace'; registered: distance"):
        softevo.evolve("land", objectives=("distnace",))


def test_simulate_of_a_file_name_says_to_load_it(tmp_path):
    """Issue 49.13: ``softevo.simulate("file.json")`` said "must be a JSON object (got str)"."""
    from softevo.sim import SceneError

    with pytest.raises(SceneError, match=r"scene: must be a dict.*'walker.json'.*json.load it first"):
        softevo.simulate("walker.json")
    with pytest.raises(SceneError, match="json.load it first"):
        softevo.simulate(tmp_path / "walker.json")
