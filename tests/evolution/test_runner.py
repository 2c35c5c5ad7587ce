"""The local run loop: it asks as the coordinator asks (``ask_generation``) and evaluates a
compound world as the workers do (``evolution.evaluation``: one scene per part, distances added)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from softevo.evolution import Evaluation, Evolution, Schedule, run
from softevo.evolution.evaluation import CompoundOutcome, compound_outcome
from softevo.evolution.runner import ask_generation, evaluations, individual_scenes
from tests.evolution.test_afpo import config, fake_evaluate

GRADUAL = Schedule([("land", 0), ("water", 2)], spans=[0, 3])  # 2, 3, 4: compound; 5: water


def test_a_gradual_transition_runs_in_compound_worlds():
    batches, worlds_of = [], {}

    def record(scenes):
        batches.append(scenes)
        return fake_evaluate(scenes)

    algo = run(
        config(cycles=4),
        record,
        generations=5,
        schedule=GRADUAL,
        on_generation=lambda done: worlds_of.update({done.generation: done.environment}),
    )
    assert worlds_of == {
        0: "land",
        1: "land",
        2: "land>water@0.250",
        3: "land>water@0.500",
        4: "land>water@0.750",
        5: "water",
    }
    first_compound = batches[2]
    assert [s["environment"]["kind"] for s in first_compound[:2]] == ["land", "water"]
    assert [s["duration"]["cycles"] for s in first_compound[:2]] == [3.0, 1.0]
    assert all(len(batch) % 2 == 0 for batch in batches[2:5])
    assert all(i.environment == "water" for i in algo.population)


def test_a_compound_evaluation_adds_its_parts_distances():
    algo = Evolution(config(environment="land>water@0.250", cycles=4))
    asked = algo.ask()
    outcomes = evaluations(algo, asked, fake_evaluate)
    for ind, outcome in zip(asked, outcomes, strict=True):
        parts = fake_evaluate(individual_scenes(algo, ind))
        assert outcome == CompoundOutcome(sum(p["distance"] for p in parts), True, None)
    algo.tell(outcomes)
    assert algo.generation_complete


def test_a_compound_outcome_fails_with_its_first_failing_part():
    stable = {"distance": 1.5, "stable": True, "reason": None}
    unstable = {"distance": 9.0, "stable": False, "reason": "diverged"}
    assert compound_outcome([stable]) is stable
    assert compound_outcome([stable, unstable]) == CompoundOutcome(10.5, False, "diverged")
    evaluations_ = [Evaluation(1.0), Evaluation(0.0, False, "strain")]
    assert compound_outcome(evaluations_) == CompoundOutcome(1.0, False, "strain")
    crash = RuntimeError("boom")
    assert compound_outcome([unstable, crash]) is crash


def test_a_compound_outcome_costs_the_sum_of_its_parts():
    land = {"distance": 1.5, "stable": True, "reason": None, "steps": 300, "simulated_seconds": 0.75}
    water = SimpleNamespace(distance=0.5, stable=True, reason=None, steps=100, simulated_seconds=0.25)
    joined = compound_outcome([land, water])
    assert joined == CompoundOutcome(2.0, True, None, steps=400, simulated_seconds=1.0)
    assert isinstance(joined.steps, int)
    # a part without a cost (an outcome stored before it was kept) adds nothing
    assert compound_outcome([land, {"distance": 1.0, "stable": True}]).steps == 300


def test_a_crashing_evaluate_fails_every_part_of_the_batch():
    def crash(scenes):
        raise RuntimeError("simulator crashed")

    algo = Evolution(config(environment="water>land@0.500"))
    outcomes = evaluations(algo, algo.ask(), crash)
    assert outcomes and all(isinstance(o, RuntimeError) for o in outcomes)
    algo.tell(outcomes)
    simulated = [i for i in algo.population if i.phenotype(algo.config.encoding).active_share > 0]
    assert simulated and all(i.failed for i in simulated)  # passive bodies are not simulated


def test_ask_generation_switches_after_breeding_and_checks_the_generation():
    algo = Evolution(config())
    algo.tell(evaluations(algo, ask_generation(algo, GRADUAL, 0), fake_evaluate))
    algo.tell(evaluations(algo, ask_generation(algo, GRADUAL, 1), fake_evaluate))
    survivors = {i.id for i in algo.population}
    asked = ask_generation(algo, GRADUAL, 2)
    assert algo.environment == "land>water@0.250" and algo.generation == 2
    assert survivors <= {i.id for i in algo.pending}  # survivors and offspring, together
    assert {i.id for i in asked} <= {i.id for i in algo.pending}
    algo.tell(evaluations(algo, asked, fake_evaluate))
    with pytest.raises(RuntimeError, match="algorithm at generation 3, run at 5"):
        ask_generation(algo, GRADUAL, 5)
