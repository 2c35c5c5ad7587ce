"""Evaluations without a simulation: survivors are never handed out again in their world,
and each generation counts what it did not simulate (reused twins, empty bodies)."""

import pytest

from softevo.evolution import Evolution, Outcome
from softevo.evolution.schedule import Schedule
from tests.evolution.test_afpo import config, evaluations


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
        assert len(asked) + counts["reused"] + counts["empty"] + counts["passive"] == len(algo.pending)
        passive = [i for i in algo.pending if i.phenotype(algo.config.encoding).active_share == 0]
        reused = [i for i in algo.pending if i.evaluated and i.error != "empty body" and i not in passive]
        assert counts["reused"] == len(reused)
        algo.tell(evaluations(algo, asked))


def test_a_survivor_handed_out_again_is_refused():
    algo = Evolution(config())
    algo.tell(evaluations(algo, algo.ask()))
    algo.ask()
    survivor = algo.population[0]
    survivor.clear_evaluation()  # as if it had to be simulated again in the same world
    algo.pending.append(survivor)
    with pytest.raises(RuntimeError, match="a survivor would be simulated again in land"):
        algo.ask()


def test_a_passive_body_is_not_simulated_and_travels_nothing():
    """Issue 49.7: a passive body (active share 0) that topples after settling travelled
    1.62 voxel lengths and sat on the quickstart's Pareto front (least active share). It
    cannot move itself: it is not simulated, and travels 0, whatever its fall would show (the
    stand-in simulator gives every robot it sees a toppler's 1.62)."""

    def toppling(scenes):
        return [Outcome.of_simulation(1.62, True) for _ in scenes]

    passive_seen = 0
    for seed in range(40):
        algo = Evolution(config(seed=seed))
        for _ in range(3):
            asked = algo.ask()
            passive = [i for i in algo.pending if i.phenotype(algo.config.encoding).active_share == 0]
            assert not {i.id for i in passive} & {i.id for i in asked}  # none handed to the simulator
            assert algo.not_simulated["passive"] == len([i for i in passive if i not in algo.population])
            algo.tell(evaluations(algo, asked, toppling))
            for ind in passive:
                assert ind.objectives["distance"] == 0.0 and ind.stable and ind.error is None
            passive_seen += len(passive)
        if passive_seen:
            break
    assert passive_seen, "no passive body in 40 seeds: the test tests nothing"
