"""Objectives as data in the evolution loop: a registered objective is computed for every
individual from its evaluation and phenotype and changes what selection keeps; the paper's
objectives give the same run as before."""

from __future__ import annotations

import numpy as np
import pytest

from softevo.evolution.algorithm import Evolution, EvolutionConfig
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import EncodingConfig
from softevo.evolution.outcome import Outcome
from softevo.evolution.selection import (
    OBJECTIVES,
    PAPER_OBJECTIVES,
    Objective,
    objective_named,
    objectives_named,
    register_objective,
    unregister_objective,
)

ENCODING = EncodingConfig(workspace=(4, 4, 4))


@pytest.fixture
def most_voxels():
    """A toy objective, maximise the voxel count, registered for one test only."""
    objective = register_objective(Objective("most_voxels", "max", lambda e, p: float(p.voxel_count)))
    yield objective
    unregister_objective("most_voxels")


def _run(objectives, generations=4):
    algo = Evolution(EvolutionConfig(population_size=6, seed=3, evaluation=EvaluationSpec(encoding=ENCODING),
                                     objectives=objectives, descriptors=False))
    for _ in range(generations):
        asked = algo.ask()
        algo.tell([Outcome(1.0) for _ in asked])  # the same distance for all
    return algo


def test_a_registered_objective_is_computed_and_selected_on(most_voxels):
    algo = _run((objective_named("distance"), most_voxels))
    for ind in algo.population:
        moved = 0.0 if ind.phenotype(ENCODING).active_share == 0 else 1.0  # a passive body: not simulated
        assert ind.objectives == {"distance": moved,
                                  "most_voxels": float(ind.phenotype(ENCODING).voxel_count)}
    fewest = _run((objective_named("distance"), Objective("voxel_count", "min")))
    mean = [np.mean([i.objectives[k] for i in a.population])
            for a, k in ((algo, "most_voxels"), (fewest, "voxel_count"))]
    assert mean[0] > mean[1]  # maximising the count keeps bigger bodies than minimising it
    restored = Evolution.from_state_json(algo.state_to_json())
    assert restored.config.objectives[1] is most_voxels


def test_registration_is_undone_and_checked(most_voxels):
    assert OBJECTIVES["most_voxels"] is most_voxels
    with pytest.raises(ValueError, match="already registered"):
        register_objective(Objective("most_voxels", "max", lambda e, p: 0.0))
    with pytest.raises(ValueError, match="already registered"):
        register_objective(Objective("age", "min", lambda e, p: 0.0))
    with pytest.raises(ValueError, match="needs a value"):
        register_objective(Objective("nothing", "max"))
    with pytest.raises(ValueError, match="maximised"):
        objective_named("most_voxels", "min")
    with pytest.raises(ValueError, match="one of the paper's"):
        unregister_objective("distance")
    assert objectives_named(()) == PAPER_OBJECTIVES


def test_the_paper_objectives_by_name_give_the_same_run():
    by_value = _run(PAPER_OBJECTIVES)
    by_name = _run(tuple(Objective(o.name, o.direction) for o in PAPER_OBJECTIVES))
    assert by_value.state_to_json() == by_name.state_to_json()
