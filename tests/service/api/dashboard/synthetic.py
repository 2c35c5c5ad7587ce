"""A synthetic paper-sized phylogeny (30 robots x 9000 generations, land -> water at 4500)
written straight into SQLite with bound parameters: the tree view's load test. Selection is
random (seeded): each generation every survivor has one child, one newcomer arrives, and 30
of the 61 are kept, so lineages branch, die out and coalesce as in a real run."""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass

import numpy as np
from sqlalchemy import Engine

from softevo.evolution.treatments import Treatment
from softevo.service.runs.submit import create

POPULATION, GENERATIONS, SWITCH = 30, 9000, 4500


@dataclass(frozen=True)
class Synthetic:
    run_id: int
    individuals: int
    final: list[int]  # database ids of the final population


def build(engine: Engine, path: str, seed: int = 1) -> Synthetic:
    treatment = Treatment(
        "land-water",
        0.1,
        population=POPULATION,
        generations=GENERATIONS,
        switch_at=SWITCH,
        workspace=(3, 3, 3),
    )
    _, (run_id,) = create(engine, "synthetic", [treatment])
    rng = np.random.default_rng(seed)
    individuals, members, evaluations = [], [], []
    next_id = 1_000_000  # clear of the ids the database gave anything else
    alive: list[int] = []
    for generation in range(GENERATIONS):
        environment = "land" if generation < SWITCH else "water"
        born = []
        parents = alive if alive else [None] * POPULATION
        for parent in parents + ([None] if alive else []):
            born.append(next_id)
            individuals.append((next_id, run_id, next_id, parent, generation, "{}"))
            evaluations.append((next_id, run_id, generation, environment, float(rng.random()), generation))
            next_id += 1
        pool = alive + born
        alive = (
            sorted(rng.choice(pool, size=POPULATION, replace=False).tolist())
            if len(pool) > POPULATION
            else pool
        )
        members.extend((run_id, generation, i, 0 if k < 5 else 1) for k, i in enumerate(alive))
    with sqlite3.connect(path) as conn:
        conn.executemany(
            "INSERT INTO individuals (id, run_id, local_id, parent_id, generation_born, genome)"
            " VALUES (?, ?, ?, ?, ?, ?)",
            individuals,
        )
        conn.executemany(
            "INSERT INTO evaluations (individual_id, run_id, generation, age, environment, stiffness,"
            " distance, active_share, voxel_count, stable)"
            " VALUES (?, ?, ?, 0, ?, 1e5, ?, 0.5, 10 + ? % 7, 1)",
            evaluations,
        )
        conn.executemany(
            "INSERT INTO population_members (run_id, generation, individual_id, front_rank, age)"
            " VALUES (?, ?, ?, ?, 0)",
            members,
        )
        conn.execute(
            "UPDATE runs SET generation = ?, status = 'finished' WHERE id = ?", (GENERATIONS - 1, run_id)
        )
    return Synthetic(run_id, len(individuals), alive)
