"""The worker's evaluation of fixed genomes gives the result dicts of the slow, obvious path
it replaced (issue 47: the host side of an evaluation): the genome developed, its scenes
written as nested JSON lists and parsed back, the shape descriptors measured on the
triangle mesh by trimesh (tests/evolution/_descriptor_reference.py). Same keys, same types,
the same distance and phenotype exactly, the descriptors within 1e-12."""

from __future__ import annotations

import json

import numpy as np
import pytest

from softevo import sim
from softevo.evolution.evaluation import EvaluationSpec, evaluation_scenes
from softevo.evolution.genotype import EncodingConfig, Genotype, develop, random_viable
from softevo.evolution.outcome import Outcome
from softevo.worker.evaluate import evaluate_batch
from softevo.worker.tasks import Task, TaskResult, json_ready
from tests.evolution._descriptor_reference import reference_describe

PAPER_ENCODING = EncodingConfig(control_mapping="evosoro-bounded", body_rule="evosoro")  # 7^3
WORLDS = ("land", "water", "land>water@0.500", "water")


@pytest.fixture(scope="module")
def tasks() -> list[dict]:
    rng = np.random.default_rng(47)
    out = []
    for k, world in enumerate(WORLDS):
        genome, _ = random_viable(rng, PAPER_ENCODING)
        spec = EvaluationSpec(
            world, 1e5, 1, model="voxcad-land-water", max_seconds=0.01, encoding=PAPER_ENCODING
        )
        task = Task.from_genome(genome, spec, id=k)
        out.append(task.to_json())
    return out


def reference_results(tasks: list[dict]) -> list[dict]:
    """Each task developed, its scenes through JSON (nested lists), all simulated in one
    batch, scored, and described by the trimesh reference."""
    developed, all_scenes = [], []
    for data in tasks:
        task = Task.from_json(data)
        spec = task.evaluation
        phenotype = develop(Genotype.from_dict(task.genome), spec.encoding)
        scenes = evaluation_scenes(phenotype, spec.environment, spec.youngs_modulus, spec.cycles,
                                   model=spec.model, max_seconds=spec.max_seconds)
        developed.append((task, phenotype, len(scenes)))
        all_scenes += json.loads(json.dumps(scenes))
    outcomes = sim.simulate_many(all_scenes, threads=1)
    results, offset = [], 0
    for task, phenotype, count in developed:
        outcome = Outcome.combine([Outcome.of_result(part) for part in outcomes[offset : offset + count]])
        offset += count
        result = TaskResult.of(task, outcome, phenotype, 0.0, describe=False).to_json()
        result["descriptors"] = json_ready(reference_describe(phenotype.body, phenotype.frequency))
        results.append(result)
    return results


def test_the_worker_gives_the_reference_results(tasks):
    fast = evaluate_batch(tasks, threads=1)
    slow = reference_results(tasks)
    assert json.loads(json.dumps(fast)) == fast  # plain JSON, as the coordinator receives it
    for got, expected in zip(fast, slow, strict=True):
        assert got.keys() == expected.keys()
        assert got["error"] is None and got["stable"] is True
        for key in got.keys() - {"seconds", "descriptors"}:
            assert got[key] == expected[key] and type(got[key]) is type(expected[key]), key
        assert got["descriptors"].keys() == expected["descriptors"].keys()
        for name, value in expected["descriptors"].items():
            assert got["descriptors"][name] == pytest.approx(value, abs=1e-12), name
            assert type(got["descriptors"][name]) is type(value), name
        assert got["distance"] != 0.0
