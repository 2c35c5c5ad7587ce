"""A hand-built experiment (SQLite) where the static S3 runs have more generations than the
others, as on the paper's grid (S3 to 9000 for the transitions, the rest to 5000):

    land S1        land, 0.001 MPa, 3 generations (0..2)
    land S3        land, 0.1 MPa,   5 generations (0..4)
    land-water S3  land -> water at 3, 0.1 MPa, 5 generations (0..4)

Two repetitions each, population 2. Every generation keeps two fresh individuals whose
distance (and voxel count, and frequency) is ``value(treatment, repetition, generation)``:
land S1 stays at 1 (+1 per repetition); land S3 grows, 10 per generation (so 20 and 21 at
generation 2, 40 and 41 at generation 4); land-water S3 is 100 + repetition.
"""

from __future__ import annotations

from sqlalchemy import Engine

from softevo.evolution.treatments import Treatment
from softevo.service.storage.experiments import NewRun, NewTreatment, create_experiment
from softevo.service.storage.generations import GenerationRecord, record_generation

TREATMENTS = (
    Treatment("land", 0.001, name="land S1", population=2, generations=3),
    Treatment("land", 0.1, name="land S3", population=2, generations=5),
    Treatment("land-water", 0.1, name="land-water S3", population=2, generations=5, switch_at=3),
)
REPETITIONS = 2


def value(treatment: str, repetition: int, generation: int) -> float:
    if treatment == "land S1":
        return 1.0 + repetition
    if treatment == "land S3":
        return 10.0 * generation + repetition
    return 100.0 + repetition


def _record(run_id: int, treatment: Treatment, repetition: int, generation: int, values) -> GenerationRecord:
    local_ids = [2 * generation, 2 * generation + 1]
    distance = values(treatment.name, repetition, generation)
    environment = treatment.environment_at(generation)
    evaluations = [
        {
            "local_id": i,
            "generation": generation,
            "age": 0,
            "environment": environment,
            "stiffness": treatment.stiffness_pa,
            "distance": distance,
            "active_share": 0.5,
            "voxel_count": int(distance),
            "frequency": distance,
            "symmetry": 0.5,
            "branching": 0.1,
            "shape_entropy": 1.0,
            "descriptors": None,
            "stable": True,
            "error": None,
            "seconds": 0.01,
        }
        for i in local_ids
    ]
    return GenerationRecord(
        run_id=run_id,
        generation=generation,
        individuals=[
            {
                "local_id": i,
                "parent_local_id": None,
                "generation_born": generation,
                "genome": {},
                "phenotype": None,
            }
            for i in local_ids
        ],
        evaluations=evaluations,
        members=[{"local_id": i, "front_rank": 0, "age": 0} for i in local_ids],
        summary={
            "environment": environment,
            "best_distance": distance,
            "mean_distance": distance,
            "front_size": 2,
        },
        state={"generation": generation},
        finished=generation + 1 == treatment.generations,
    )


def build(
    engine: Engine, treatments=TREATMENTS, repetitions: int = REPETITIONS, values=value, name="matched"
) -> int:
    """Create and fill the experiment (by default the one above; ``values(treatment name,
    repetition, generation)`` gives each generation's distance); return its id."""
    new = [
        NewTreatment(t.name, t.to_settings(), [NewRun(r, r, t.generations) for r in range(repetitions)])
        for t in treatments
    ]
    with engine.begin() as conn:
        experiment_id, run_ids = create_experiment(conn, name, new)
    runs = [(t, r) for t in treatments for r in range(repetitions)]
    for run_id, (treatment, repetition) in zip(run_ids, runs, strict=True):
        for generation in range(treatment.generations):
            with engine.begin() as conn:
                record_generation(conn, _record(run_id, treatment, repetition, generation, values))
    return experiment_id
