import json
from functools import partial

import numpy as np
import pytest

from softevo.evolution import EncodingConfig, Evolution, EvolutionConfig, Outcome, run
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.runner import individual_scenes
from softevo.evolution.schedule import Schedule
from softevo.evolution.selection import non_dominated_sort, objective_matrix

SMALL = EncodingConfig(workspace=(4, 4, 4))


def fake_evaluate(scenes):
    """Deterministic stand-in for the simulator: rewards active voxels and frequency."""
    results = []
    for scene in scenes:
        body = np.array(scene["body"])
        distance = float((body == 2).sum()) * scene["actuation"]["frequency"] / 10
        results.append(Outcome.of_simulation(distance, True))
    return results


def evaluate(simulator=fake_evaluate):
    """The one evaluation (the workers', ``worker.evaluate.evaluate_generation``) with
    ``simulator`` standing in for the engine: ``run``'s ``evaluate``."""
    from softevo.worker.evaluate import evaluate_generation

    return partial(evaluate_generation, simulator=simulator)


def evaluations(algo, asked, simulator=fake_evaluate):
    """The outcomes ({id: Outcome}) of ``asked`` through the one evaluation."""
    return evaluate(simulator)(algo, asked, algo.generation)


def config(**changes):
    """A small config; evaluation fields (cycles, environment, ...) go into its spec."""
    spec = {key: changes.pop(key) for key in list(changes) if key in EvaluationSpec.__dataclass_fields__}
    return EvolutionConfig(
        **{"population_size": 6, "evaluation": EvaluationSpec(**{"encoding": SMALL, **spec}),
           "descriptors": False, **changes}
    )


def summary(algo):
    return [(i.id, i.parent_id, i.age, i.genome.to_json(), i.objectives) for i in algo.population]


def test_population_size_ids_and_ages():
    algo = run(config(), evaluate(), generations=5)
    assert algo.generation == 5 and len(algo.population) == 6
    ids = [i.id for i in algo.population]
    assert len(set(ids)) == 6 and max(ids) < algo.next_id
    # generation 0: 6 newcomers; each later generation: 6 children + 1 newcomer
    assert algo.next_id == 6 + 5 * 7
    for ind in algo.population:
        assert 0 <= ind.generation_born <= 5
        if ind.parent_id is None:  # a newcomer: age 0 at birth, one more each generation since
            assert ind.age == 5 - ind.generation_born
        else:  # a child inherits its parent's age (at least 1 once the parent has aged)
            assert ind.age > 5 - ind.generation_born


def test_afpo_generation_keeps_the_first_front():
    algo = Evolution(config(seed=3))
    algo.tell(evaluations(algo, algo.ask()))
    for _ in range(4):
        before = list(algo.population)
        asked = algo.ask()
        assert len(asked) <= 7  # 6 children + 1 newcomer (twins and empties need no sim)
        assert sum(1 for i in algo.pending if i.parent_id is None) == 1
        pending = list(algo.pending)
        algo.tell(evaluations(algo, asked))
        combined = before + pending
        F = objective_matrix(
            [{**i.objectives, "age": i.age} for i in combined],
            algo.config.selection_objectives,
        )
        ranks = non_dominated_sort(F)
        front = {combined[k].id for k in np.flatnonzero(ranks == 0)}
        kept = {i.id for i in algo.population}
        assert len(kept) == 6
        if len(front) <= 6:
            assert front <= kept


def test_children_inherit_age_and_newcomers_start_at_zero():
    algo = Evolution(config())
    algo.tell(evaluations(algo, algo.ask()))
    parents = {i.id: i.age for i in algo.population}
    algo.ask()
    for child in algo.pending:
        if child.parent_id is None:
            assert child.age == 0 and child.generation_born == 1
        else:
            assert child.age == parents[child.parent_id] + 1
            assert child.mutations


def test_pareto_mode_has_no_newcomer_and_no_age_objective():
    algo = Evolution(config(mode="pareto"))
    algo.tell(evaluations(algo, algo.ask()))
    algo.ask()
    assert all(i.parent_id is not None for i in algo.pending)
    assert [o.name for o in algo.config.selection_objectives] == [
        "distance",
        "active_share",
        "voxel_count",
    ]


def test_same_seed_same_population_and_different_seed_differs():
    a = run(config(seed=5), evaluate(), generations=4)
    b = run(config(seed=5), evaluate(), generations=4)
    c = run(config(seed=6), evaluate(), generations=4)
    assert summary(a) == summary(b)
    assert summary(a) != summary(c)


def test_state_json_round_trip_and_identical_resume():
    uninterrupted = run(config(seed=9), evaluate(), generations=6)
    first = run(config(seed=9), evaluate(), generations=3)
    text = first.state_to_json()
    json.loads(text)  # plain JSON
    resumed = Evolution.from_state_json(text)
    assert resumed.state_to_json() == text
    resumed = run(resumed.config, evaluate(), generations=6, algo=resumed)
    assert resumed.state_to_json() == uninterrupted.state_to_json()


def test_resume_with_pending_offspring():
    algo = run(config(seed=2), evaluate(), generations=2)
    asked = algo.ask()
    restored = Evolution.from_state_json(algo.state_to_json())
    assert [i.id for i in restored.ask()] == [i.id for i in asked]
    restored.tell(evaluations(restored, restored.ask()))
    algo.tell(evaluations(algo, asked))
    assert restored.state_to_json() == algo.state_to_json()


def test_tell_by_id_in_any_order_and_partial():
    algo = Evolution(config())
    asked = algo.ask()
    results = evaluations(algo, asked)
    assert set(results) == {i.id for i in asked}
    ids = list(results)[::-1]
    algo.tell({k: results[k] for k in ids[:2]})
    assert not algo.generation_complete
    assert {i.id for i in algo.ask()} == set(ids[2:])
    algo.tell({k: results[k] for k in ids[2:]})
    assert algo.generation_complete
    with pytest.raises(KeyError):
        algo.tell({999: Outcome(1.0)})


def test_tell_takes_outcomes_only():
    algo = Evolution(config())
    asked = algo.ask()
    with pytest.raises(TypeError, match="an Outcome, not dict"):
        algo.tell({asked[0].id: {"distance": 1.0, "stable": True}})
    assert not asked[0].evaluated


def test_failed_evaluations_get_the_worst_rank_and_the_run_goes_on():
    calls = {"n": 0}

    def flaky(scenes):
        calls["n"] += 1
        if calls["n"] == 2:
            raise RuntimeError("simulator crashed")
        results = fake_evaluate(scenes)
        results[0] = Outcome.of_simulation(float("nan"), False, "strain > 100")
        return results

    algo = run(config(population_size=5), evaluate(flaky), generations=3)
    assert algo.generation == 3 and len(algo.population) == 5
    failed = Outcome.of_simulation(9.0, False, "diverged")
    assert failed.distance == 0.0 and failed.error == "diverged"
    crashed = Outcome.crash(RuntimeError("boom"))
    assert crashed.error == "RuntimeError: boom" and not crashed.stable


def test_environment_switch_reevaluates_everyone():
    seen, survivors, empty = [], {}, {}

    def record(scenes):
        seen.append([s["environment"]["kind"] for s in scenes])
        return fake_evaluate(scenes)

    def done(algo):
        survivors[algo.generation] = {i.id for i in algo.population}
        empty[algo.generation] = algo.not_simulated["empty"] + algo.not_simulated["passive"]  # not simulated

    algo = run(config(), evaluate(record), generations=4, on_generation=done,
               schedule=Schedule.from_until([("land", 2), ("water", 10)]))
    assert [set(batch) for batch in seen] == [{"land"}, {"land"}, {"water"}, {"water"}, {"water"}]
    assert len(seen[0]) + empty[0] == 6  # passive bodies are not simulated (issue 49.7)
    # generation 2, the first in water, breeds first, then evaluates the land survivors and
    # their offspring there, all in that generation (as the coordinator does)
    assert len(seen[2]) + empty[2] == 6 + 7
    assert survivors[2] <= survivors[1] | set(range(13, 20))  # ids 13..19 born in generation 2
    assert all(i.environment == "water" for i in algo.population)
    assert all(i.evaluated_generation >= 2 for i in algo.population)
    (water_scene,) = individual_scenes(algo, algo.population[0])
    assert water_scene["settle_seconds"] == 0.0


def test_known_phenotypes_are_not_simulated_twice():
    algo = Evolution(config())
    algo.tell(evaluations(algo, algo.ask()))
    twin = algo.population[0]
    algo.ask()
    copy = algo.pending[0]
    copy.genome = twin.genome  # force a twin of a living individual
    copy.clear_evaluation()
    algo._fill_known()
    assert copy.evaluated and copy.objectives == twin.objectives
    assert copy.id not in {i.id for i in algo.ask()}


def test_descriptors_are_recorded():
    algo = run(config(descriptors=True, population_size=3), evaluate(), generations=1)
    for ind in algo.population:
        assert set(ind.descriptors) >= {
            "symmetry",
            "branching",
            "shape_entropy",
            "frequency",
            "active_share",
            "voxel_count",
        }
