"""A small hand-built run with a known phylogeny (land -> water, switch at generation 2).

gen 0: newcomers 1, 2, 3 (land); kept 1, 2, 3
gen 1: 4 <- 1, 5 <- 2, newcomer 6 (land); kept 1, 4, 5
gen 2: switch: 1, 4, 5 re-evaluated in water; 7 <- 4, 8 <- 5, newcomer 9; kept 4, 7, 8
gen 3: 10 <- 7, 11 <- 8, newcomer 12 (water); kept 7, 10, 11

Traits: voxel_count = 10 * local id except 4 keeps its parent's 10 and 10 keeps 7's 70;
active_share 0.5 for all but 7 (0.25) and its child 10 (0.25).
"""

from __future__ import annotations

from sqlalchemy import Engine

from softevo.evolution.treatments import Treatment
from softevo.service.storage.experiments import NewRun, NewTreatment, create_experiment
from softevo.service.storage.generations import GenerationRecord, record_generation

TREATMENT = Treatment("land-water", 0.1, population=3, generations=4, switch_at=2)
PARENTS = {4: 1, 5: 2, 7: 4, 8: 5, 10: 7, 11: 8}
BORN = {1: 0, 2: 0, 3: 0, 4: 1, 5: 1, 6: 1, 7: 2, 8: 2, 9: 2, 10: 3, 11: 3, 12: 3}
EVALUATED = {0: [1, 2, 3], 1: [4, 5, 6], 2: [1, 4, 5, 7, 8, 9], 3: [10, 11, 12]}
KEPT = {0: [1, 2, 3], 1: [1, 4, 5], 2: [4, 7, 8], 3: [7, 10, 11]}


def voxel_count(local_id: int) -> int:
    return {4: 10, 10: 70}.get(local_id, 10 * local_id)


def active_share(local_id: int) -> float:
    return 0.25 if local_id in (7, 10) else 0.5


def distance(local_id: int, environment: str) -> float:
    return local_id * (1.0 if environment == "land" else 2.0)


def generation_record(run_id: int, generation: int) -> GenerationRecord:
    environment = TREATMENT.environment_at(generation)
    new = [i for i in EVALUATED[generation] if BORN[i] == generation]
    evaluations = [
        {
            "local_id": i,
            "generation": generation,
            "age": generation - BORN[i],
            "environment": environment,
            "stiffness": TREATMENT.stiffness_pa,
            "distance": distance(i, environment),
            "active_share": active_share(i),
            "voxel_count": voxel_count(i),
            "frequency": 2.0,
            "symmetry": 0.5,
            "branching": 0.1,
            "shape_entropy": 1.0,
            "descriptors": {"extra": i},
            "stable": i != 9,
            "error": "unstable: strain" if i == 9 else None,
            "seconds": 0.01,
        }
        for i in EVALUATED[generation]
    ]
    distances = [e["distance"] for e in evaluations]
    return GenerationRecord(
        run_id=run_id,
        generation=generation,
        individuals=[
            {
                "local_id": i,
                "parent_local_id": PARENTS.get(i),
                "generation_born": generation,
                "genome": {"nodes": [i]},
                "phenotype": {"voxels": voxel_count(i)},
            }
            for i in new
        ],
        evaluations=evaluations,
        members=[
            {"local_id": i, "front_rank": 0 if k == 0 else 1, "age": generation - BORN[i]}
            for k, i in enumerate(KEPT[generation])
        ],
        summary={
            "environment": environment,
            "best_distance": max(distances),
            "mean_distance": sum(distances) / len(distances),
            "front_size": 1,
        },
        state={"generation": generation, "rng": {"state": 2**100 + generation}},
        finished=generation == 3,
    )


def build(engine: Engine) -> int:
    """Create the hand-built run; return its run id."""
    with engine.begin() as conn:
        _, (run_id,) = create_experiment(
            conn, "hand", [NewTreatment("lw", TREATMENT.to_settings(), [NewRun(0, 7, 4)])]
        )
    for generation in range(4):
        with engine.begin() as conn:
            record_generation(conn, generation_record(run_id, generation))
    return run_id


def db_id(engine: Engine, run_id: int, local_id: int) -> int:
    from softevo.service.storage.individuals import local_to_db_ids

    with engine.connect() as conn:
        return local_to_db_ids(conn, run_id, [local_id])[local_id]
