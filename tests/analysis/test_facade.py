"""The notebook API at ``softevo``: each function gives what its layer gives."""

from __future__ import annotations

import numpy as np

import softevo
from softevo import sim
from softevo.evolution.descriptors import describe


def test_load_experiment_is_the_stored_experiment(tiny, tiny_data):
    data = softevo.load_experiment(tiny.url, f"e{tiny.experiment_id}")
    assert data.experiment == tiny_data.experiment
    assert data.runs["run_id"].tolist() == tiny_data.runs["run_id"].tolist()
    assert data.generations.equals(tiny_data.generations)
    latest = softevo.load_experiment(tiny.url)  # "latest" by default
    assert latest.experiment["id"] == tiny.experiment_id


def test_simulate_and_describe_are_the_layers_functions():
    body = np.array([[[2]], [[1]], [[2]]])
    scene = {"body": body.tolist(), "duration": {"cycles": 1}}
    assert softevo.simulate(scene).distance == sim.simulate(scene).distance
    assert softevo.simulate_many([scene])[0].distance == sim.simulate(scene).distance
    assert softevo.describe(body, 2.0) == describe(body, 2.0)


def test_evolve_runs_in_memory():
    algo = softevo.evolve("water", 0.1, population=4, generations=1, workspace=(3, 3, 3), cycles=1)
    assert algo.generation == 1 and len(algo.population) == 4
    assert all(ind.evaluated for ind in algo.population)
    again = softevo.evolve("water", 0.1, population=4, generations=1, workspace=(3, 3, 3), cycles=1)
    assert [i.objectives for i in again.population] == [i.objectives for i in algo.population]
