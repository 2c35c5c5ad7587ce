"""Evaluations without a simulation: survivors are never handed out again in their world,
and each generation counts what it did not simulate (reused twins, empty bodies)."""

import pytest

from softevo.evolution import Evolution
from softevo.evolution.runner import evaluations
from softevo.evolution.schedule import Schedule
from tests.evolution.test_afpo import config, fake_evaluate


def test_each_generation_counts_what_it_did_not_simulate():
    algo = Evolution(config())
    schedule = Schedule([("land", 0), ("water", 3)])
    for generation in range(6):
        asked = algo.ask()
        if generation and schedule.switch(algo, generation):
            asked = algo.ask()
            assert len(algo.pending) == 6 + 7  # survivors and offspring, all in water
        survivors = {ind.id for ind in algo.population}
        assert not survivors & {ind.id for ind in asked}
        counts = algo.not_simulated
        assert len(asked) + counts["reused"] + counts["empty"] == len(algo.pending)
        reused = [i for i in algo.pending if i.evaluated and i.error != "empty body"]
        assert counts["reused"] == len(reused)
        algo.tell(evaluations(algo, asked, fake_evaluate))


def test_a_survivor_handed_out_again_is_refused():
    algo = Evolution(config())
    algo.tell(evaluations(algo, algo.ask(), fake_evaluate))
    algo.ask()
    survivor = algo.population[0]
    survivor.clear_evaluation()  # as if it had to be simulated again in the same world
    algo.pending.append(survivor)
    with pytest.raises(RuntimeError, match="a survivor would be simulated again in land"):
        algo.ask()
