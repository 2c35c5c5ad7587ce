"""Acceptance: a 20-generation run with the real simulator improves the best distance."""

import pytest

from softevo.evolution import EncodingConfig, EvolutionConfig, run
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.runner import best_distance
from softevo.worker.evaluate import evaluate_generation


@pytest.mark.slow
def test_twenty_generations_on_land_improve_the_best_distance():
    config = EvolutionConfig(
        population_size=12,
        seed=1,
        # short evaluations keep the test around a minute on 2 cores
        evaluation=EvaluationSpec("land", 1e6, cycles=4, encoding=EncodingConfig(workspace=(5, 5, 5))),
    )
    best = {}

    def record(algo):
        best[algo.generation] = best_distance(algo)

    algo = run(config, evaluate_generation, generations=20, on_generation=record)
    assert algo.generation == 20 and len(algo.population) == 12
    assert sorted(best) == list(range(21))
    assert best[20] > best[0]
