"""A local run (``evolution.runner.run``, ``softevo.evolve``) of a treatment is the run the
coordinator stores with the same seed: the same survivors at every generation, each with
the same distance, world and generation of its evaluation, for a static world, an abrupt
switch (AFPO and the paper's Pareto selection) and a gradual one (compound worlds)."""

from __future__ import annotations

import dataclasses

import pytest

import softevo
from softevo.evolution.runner import run
from softevo.evolution.treatments import Treatment
from softevo.worker.evaluate import evaluate_generation
from tests.service import tinyrun

SMALL = Treatment("water", 0.1, population=4, generations=4, workspace=(3, 3, 3), cycles=1, seed=3)
TREATMENTS = {
    "static": SMALL,
    "abrupt": dataclasses.replace(SMALL, environment="land-water", switch_at=2),
    "abrupt-pareto": dataclasses.replace(SMALL, environment="water-land", switch_at=2, algorithm="pareto"),
    "gradual": dataclasses.replace(
        SMALL, environment="land-water", switch_at=1, switch_over=2, generations=5
    ),
}


Survivor = tuple[int, str, float, int]  # local id, world, distance, generation evaluated


def stored_survivors(snapshot) -> dict[int, list[Survivor]]:
    """{generation: [survivor, ...]} of a stored run, each survivor with its latest
    evaluation up to that generation."""
    latest: dict[int, tuple[str, float, int]] = {}
    by_generation: dict[int, list[Survivor]] = {}
    evaluations = snapshot["evaluations"]  # (local id, generation, world, age, distance, ...)
    for generation in sorted({m[0] for m in snapshot["members"]}):
        latest.update({e[0]: (e[2], e[4], e[1]) for e in evaluations if e[1] == generation})
        members = sorted(m[1] for m in snapshot["members"] if m[0] == generation)
        by_generation[generation] = [(local, *latest[local]) for local in members]
    return by_generation


def local_survivors(treatment: Treatment) -> dict[int, list[Survivor]]:
    """{generation: [survivor, ...]} of a local run of ``treatment``."""
    survivors = {}

    def record(algo) -> None:
        survivors[algo.generation] = sorted(
            (i.id, i.environment, i.objectives["distance"], i.evaluated_generation) for i in algo.population
        )

    run(
        treatment.evolution_config(treatment.seed),
        evaluate_generation,
        treatment.generations - 1,
        schedule=treatment.schedule(),
        on_generation=record,
    )
    return survivors


@pytest.mark.parametrize("name", list(TREATMENTS))
def test_a_local_run_is_the_coordinators_run(name, tmp_path):
    treatment = TREATMENTS[name]
    stored = stored_survivors(tinyrun.reference_snapshot(tmp_path, treatment))
    local = local_survivors(treatment)
    assert sorted(local) == list(range(treatment.generations))
    assert local == stored
    worlds = [survivors[0][1] for _, survivors in sorted(local.items())]
    assert worlds == [treatment.environment_at(g) for g in range(treatment.generations)]


def test_softevo_evolve_runs_a_gradual_transition_as_softevo_run_does(tmp_path):
    treatment = TREATMENTS["gradual"]
    stored = stored_survivors(tinyrun.reference_snapshot(tmp_path, treatment))
    fields = ("population", "generations", "workspace", "cycles", "seed", "switch_at", "switch_over")
    local = softevo.evolve(
        treatment.environment, treatment.stiffness_mpa, **{key: getattr(treatment, key) for key in fields}
    )
    assert [row["environment"] for row in local.history] == [
        "land",
        "land>water@0.333",
        "land>water@0.667",
        "water",
        "water",
    ]
    assert [row["best_distance"] for row in local.history] == [
        max(distance for _, _, distance, _ in stored[g]) for g in range(5)
    ]
