"""A hand-made ``ExperimentData`` of the paper's grid (no database, no simulation): every run
stores every generation, each population of one member whose distance and frequency are
``values(treatment, repetition, generation)``. The treatments are ``paper_grid("tiny")``'s,
with ``generations`` generations for every treatment and the transitions switching at
``switch_at``."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import pandas as pd

from softevo.analysis.data import ExperimentData
from softevo.evolution.treatments import paper_grid

Values = Callable[[str, int, int], tuple[float, float]]  # (best distance, frequency)


def grid_data(
    values: Values,
    repetitions: int = 5,
    generations: int = 6,
    switch_at: int = 3,
    keep: Callable[[str], bool] = lambda name: True,
) -> ExperimentData:
    """The grid's treatments that ``keep`` accepts, ``repetitions`` runs each (run ids and
    seeds counting up), ``generations`` generations, values from ``values``."""
    treatments, runs, summaries, members = [], [], [], []
    for t in paper_grid("tiny"):
        if not keep(t.name):
            continue
        switch = switch_at if t.switch_generation() is not None else None
        t = dataclasses.replace(t, generations=generations, switch_at=switch)
        treatments.append(
            t.to_settings()
            | {
                "name": t.name,
                "switch_at": switch,
                "schedule": t.schedule_text(),
                "workspace": "x".join(map(str, t.workspace)),
            }  # fmt: skip
        )
        for r in range(repetitions):
            run_id = len(runs) + 1
            runs.append({"run_id": run_id, "treatment": t.name, "repetition": r, "seed": 100 + run_id,
                         "status": "finished", "generations": generations,
                         "generation": generations - 1})  # fmt: skip
            for g in range(generations):
                distance, frequency = values(t.name, r, g)
                world = t.environment_at(g)
                summaries.append({"run_id": run_id, "treatment": t.name, "repetition": r, "generation": g,
                                  "environment": world, "best_distance": distance, "mean_distance": distance,
                                  "front_size": 1, "evaluations": 1, "evaluation_seconds": 0.1,
                                  "created_at": pd.Timestamp("2026-01-01")})  # fmt: skip
                members.append({"run_id": run_id, "treatment": t.name, "repetition": r, "generation": g,
                                "individual_id": 1000 * run_id + g, "front_rank": 0, "environment": world,
                                "stable": True, "distance": distance, "active_share": 0.5,
                                "voxel_count": 20, "frequency": frequency, "symmetry": 0.5,
                                "branching": 0.1, "shape_entropy": 1.0,
                                "evaluation_generation": g})  # fmt: skip
    frame = pd.DataFrame(treatments)
    frame["switch_at"] = frame["switch_at"].astype("Int64")
    populations = pd.DataFrame(members)
    return ExperimentData(
        {"id": 1, "name": "grid", "created_at": pd.Timestamp("2026-01-01")},
        frame,
        pd.DataFrame(runs),
        populations.drop(columns=["front_rank"]),
        pd.DataFrame(summaries),
        populations,
    )
