"""Algorithms as registered records of operators (``evolution.algorithm.Algorithm``,
``evolution.operators``): ``afpo`` and ``pareto`` are two registrations that breed and select
exactly as before they were, and a toy algorithm registered in the test runs through the
runner and ``softevo.evolve`` with nothing else written for it."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest

import softevo
from softevo.errors import UserError
from softevo.evolution import EncodingConfig, Evolution, EvolutionConfig, algorithm
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.operators import Candidates, truncation
from softevo.evolution.runner import ask_generation
from softevo.evolution.schedule import Schedule
from softevo.evolution.selection import AGE_OBJECTIVE, PAPER_OBJECTIVES
from tests.evolution.test_afpo import config, evaluations
from tests.evolution.toy_algorithm import NAME, register_toy

EVOLUTION = Path(__file__).resolve().parents[2] / "evolution"

# sha256 (first 16 hex digits) of the state after 8 generations with the stand-in simulator,
# descriptors left out, computed with the code before algorithms were records (8f77765)
BEFORE = {"afpo": "56b53be6c82af942", "afpo-gradual": "581c071b99d97510",
          "pareto": "c57af0bc26aa2f6f", "pareto-gradual": "fafe5dc6df93da79"}


def state_digest(mode: str, schedule: Schedule) -> str:
    spec = EvaluationSpec("land", 1e6, 2, encoding=EncodingConfig(workspace=(4, 4, 4)))
    algo = Evolution(EvolutionConfig(population_size=6, mode=mode, seed=11, descriptors=False,
                                     evaluation=spec))
    for generation in range(8):
        asked = ask_generation(algo, schedule, generation)
        algo.tell(evaluations(algo, asked))
    state = algo.state_to_dict()
    for ind in state["population"] + state["pending"]:
        ind.pop("descriptors")
    return hashlib.sha256(json.dumps(state, sort_keys=True).encode()).hexdigest()[:16]


@pytest.mark.parametrize("name", list(BEFORE))
def test_afpo_and_pareto_run_as_before_they_were_records(name):
    mode, _, gradual = name.partition("-")
    schedule = Schedule([("land", 0), ("water", 3)], spans=[0, 3]) if gradual else Schedule.static("land")
    assert state_digest(mode, schedule) == BEFORE[name]


def test_the_built_in_algorithms_are_registrations_of_operators():
    assert algorithm.names() == ("afpo", "pareto", "map-elites")
    afpo, pareto = algorithm.get("afpo"), algorithm.get("pareto")
    assert afpo.objectives == (AGE_OBJECTIVE,) and pareto.objectives == ()
    assert len(afpo.variations) == 2 and len(pareto.variations) == 1
    assert EvolutionConfig(mode="afpo").selection_objectives == PAPER_OBJECTIVES + (AGE_OBJECTIVE,)
    with pytest.raises(ValueError, match="mode must be one of \\('afpo', 'pareto', 'map-elites'\\)"):
        EvolutionConfig(mode="toy")
    with pytest.raises(ValueError, match="algorithm 'afpo' is built in"):
        algorithm.unregister("afpo")


def test_no_algorithm_is_compared_by_name_in_the_evolution_core():
    name = r"""["'](?:afpo|pareto)["']"""
    comparison = re.compile(rf"""[=!]=\s*{name}|{name}\s*[=!]=|\bin\s*\(\s*{name}""")
    found = [f"{path.name}: {line.strip()}" for path in EVOLUTION.glob("*.py")
             for line in path.read_text(encoding="utf-8").splitlines() if comparison.search(line)]
    assert not found


def test_truncation_keeps_the_best_valid_rows_by_id():
    F = np.array([[-1.0, 0], [-3.0, 1], [-3.0, 2], [-9.0, 3]])  # distance (maximised) first
    candidates = Candidates(F, PAPER_OBJECTIVES[:2], np.zeros(4, int), np.array([True, True, True, False]))
    assert truncation("distance")(candidates, 2, np.random.default_rng(0)).tolist() == [1, 2]
    assert truncation("active_share")(candidates, 1, np.random.default_rng(0)).tolist() == [0]


def test_a_registered_toy_runs_its_operators_through_the_one_evaluation():
    with register_toy():
        assert algorithm.names() == ("afpo", "pareto", "map-elites", NAME)
        algo = Evolution(config(mode=NAME))
        algo.tell(evaluations(algo, algo.ask()))
        for _ in range(3):
            before = list(algo.population)
            asked = algo.ask()
            pending = list(algo.pending)
            assert len(pending) == 2 * len(before)  # two children a survivor, no newcomer
            assert all(child.parent_id is not None for child in pending)
            algo.tell(evaluations(algo, asked))
            everyone = before + pending
            kept = {ind.id for ind in algo.population}
            worst_kept = min(ind.objectives["distance"] for ind in algo.population)
            assert len(kept) == 6
            assert all(ind.objectives["distance"] <= worst_kept for ind in everyone
                       if ind.id not in kept and not ind.failed)
        # its name is all a stored state holds of it
        assert Evolution.from_state_json(algo.state_to_json()).config.algorithm.name == NAME
    assert NAME not in algorithm.names()


def test_softevo_evolve_runs_a_registered_algorithm():
    with register_toy():
        local = softevo.evolve("land", 1.0, population=3, generations=2, workspace=(3, 3, 3), cycles=1,
                               seed=4, algorithm=NAME)
    assert local.evolution.config.mode == NAME and len(local.history) == 2
    assert local.evolution.next_id == 3 + 2 * 3  # generation 1: two children a survivor
    with pytest.raises(UserError, match="unknown algorithm 'toy'; choose one of afpo, pareto"):
        softevo.evolve("land", 1.0, algorithm=NAME)
