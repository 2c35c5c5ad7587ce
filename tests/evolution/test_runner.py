"""The local run loop: it asks as the coordinator asks (``ask_generation``) and evaluates
through the workers' one path, a compound world as one scene per part whose outcomes
``Outcome.combine`` adds."""

from __future__ import annotations

import pytest

from softevo.evolution import Evolution, Outcome, Schedule, run
from softevo.evolution.runner import ask_generation, individual_scenes
from tests.evolution.test_afpo import config, evaluate, evaluations, fake_evaluate

GRADUAL = Schedule([("land", 0), ("water", 2)], spans=[0, 3])  # 2, 3, 4: compound; 5: water


def test_a_gradual_transition_runs_in_compound_worlds():
    batches, worlds_of = [], {}

    def record(scenes):
        batches.append(scenes)
        return fake_evaluate(scenes)

    algo = run(
        config(cycles=4),
        evaluate(record),
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
    outcomes = evaluations(algo, asked)
    for ind in asked:
        parts = fake_evaluate(individual_scenes(algo, ind))
        assert len(parts) == 2
        assert outcomes[ind.id].distance == sum(p.distance for p in parts) and outcomes[ind.id].ok
    algo.tell(outcomes)
    assert algo.generation_complete


def test_a_compound_outcome_fails_with_its_first_failing_part():
    stable = Outcome.of_simulation(1.5, True)
    unstable = Outcome.of_simulation(9.0, False, "diverged")
    assert Outcome.combine([stable]) is stable
    assert Outcome.combine([stable, unstable]) == Outcome(0.0, False, "diverged")
    assert Outcome.combine([Outcome(1.0), Outcome.of_simulation(0.0, False, "strain")]).error == "strain"
    crash = Outcome.crash(RuntimeError("boom"))
    assert Outcome.combine([stable, crash]).error == "RuntimeError: boom"
    assert Outcome.combine([stable, Outcome.of_simulation(float("nan"), True)]).error == "non-finite distance"


def test_a_compound_outcome_costs_the_sum_of_its_parts():
    land = Outcome.of_simulation(1.5, True, steps=300, simulated_seconds=0.75)
    water = Outcome.of_simulation(0.5, True, steps=100, simulated_seconds=0.25)
    joined = Outcome.combine([land, water])
    assert joined == Outcome(2.0, True, None, steps=400, simulated_seconds=1.0)
    assert isinstance(joined.steps, int)
    # a part without a cost adds nothing
    assert Outcome.combine([land, Outcome(1.0)]).steps == 300


def test_an_outcome_round_trips_its_json():
    outcome = Outcome(1.25, True, None, 40, 0.5, {"symmetry": 0.5})
    assert Outcome.from_json(outcome.to_json()) == outcome
    # an error fails even a stable outcome read from elsewhere
    assert Outcome.from_json({"distance": 3.0, "stable": True, "error": "lost"}).distance == 0.0


def test_a_crashing_simulator_fails_every_part_of_the_batch():
    def crash(scenes):
        raise RuntimeError("simulator crashed")

    algo = Evolution(config(environment="water>land@0.500"))
    outcomes = evaluations(algo, algo.ask(), crash)
    assert outcomes and all(o.error == "RuntimeError: simulator crashed" for o in outcomes.values())
    algo.tell(outcomes)
    simulated = [i for i in algo.population if i.phenotype(algo.config.encoding).active_share > 0]
    assert simulated and all(i.failed for i in simulated)  # passive bodies are not simulated


def test_ask_generation_switches_after_breeding_and_checks_the_generation():
    algo = Evolution(config())
    algo.tell(evaluations(algo, ask_generation(algo, GRADUAL, 0)))
    algo.tell(evaluations(algo, ask_generation(algo, GRADUAL, 1)))
    survivors = {i.id for i in algo.population}
    asked = ask_generation(algo, GRADUAL, 2)
    assert algo.environment == "land>water@0.250" and algo.generation == 2
    assert survivors <= {i.id for i in algo.pending}  # survivors and offspring, together
    assert {i.id for i in asked} <= {i.id for i in algo.pending}
    algo.tell(evaluations(algo, asked))
    with pytest.raises(RuntimeError, match="algorithm at generation 3, run at 5"):
        ask_generation(algo, GRADUAL, 5)
