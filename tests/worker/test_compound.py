"""A compound world's evaluation (a gradual transition): its parts are the task's two
worlds with the cycles split by the share, its distance is the sum of the parts' distances,
and it is deterministic; replay joins the parts' frames in time."""

from __future__ import annotations

import numpy as np
import pytest

from softevo import sim
from softevo.evolution import environments
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import EncodingConfig, random_viable_genotype
from softevo.worker.evaluate import evaluate_batch
from softevo.worker.tasks import Task, replay, scene_of, scenes_of


@pytest.fixture(scope="module")
def genome():
    return random_viable_genotype(np.random.default_rng(4), EncodingConfig(workspace=(3, 3, 3)))


def task(genome, environment: str, cycles: int = 2) -> Task:
    encoding = EncodingConfig(workspace=(3, 3, 3))
    return Task.from_genome(genome, EvaluationSpec(environment, 1e5, cycles, encoding=encoding))


def test_world_names_round_trip():
    name = environments.compound("land", "water", environments.share_at(0, 3))
    assert name == "land>water@0.250" and len(name) <= 20
    assert environments.parts(name) == [("land", 0.75), ("water", 0.25)]
    assert environments.parts("water") == [("water", 1.0)]
    with pytest.raises(ValueError, match="bad compound world"):
        environments.parts("land>water@1.5")


def test_compound_distance_is_the_sum_of_its_parts(genome):
    compound = task(genome, "land>water@0.250", cycles=4)
    _, scenes = scenes_of(compound)
    assert [s["environment"]["kind"] for s in scenes] == ["land", "water"]
    assert [s["duration"]["cycles"] for s in scenes] == [3.0, 1.0]
    parts = sim.simulate_many(scenes, threads=1)
    (result,) = evaluate_batch([compound.to_json()], threads=1)
    assert result["stable"] and result["error"] is None
    assert result["distance"] == sum(p.distance for p in parts)
    assert evaluate_batch([compound.to_json()], threads=1)[0]["distance"] == result["distance"]
    pure = evaluate_batch([task(genome, "land", cycles=4).to_json()], threads=1)[0]
    assert pure["distance"] != result["distance"]
    with pytest.raises(ValueError, match="compound world"):
        scene_of(compound)


def test_a_compound_evaluation_costs_the_sum_of_its_parts(genome):
    compound = task(genome, "land>water@0.250", cycles=4)
    _, scenes = scenes_of(compound)
    parts = sim.simulate_many(scenes, threads=1)
    (result,) = evaluate_batch([compound.to_json()], threads=1)
    assert all(p.steps > 0 for p in parts)
    assert result["steps"] == sum(p.steps for p in parts)
    assert result["simulated_seconds"] == pytest.approx(sum(p.simulated_seconds for p in parts))


def test_replay_joins_the_parts(genome):
    motion = replay(task(genome, "water>land@0.500"), every=200)
    assert np.all(np.diff(motion["t"]) > 0)
    (result,) = evaluate_batch([task(genome, "water>land@0.500").to_json()], threads=1)
    assert float(motion["distance"]) == pytest.approx(result["distance"])
