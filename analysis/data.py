"""An experiment read from the database into pandas DataFrames, the input of every analysis.

``load_experiment(engine, experiment_id)`` gathers, for all runs of one experiment:

- ``treatments``: one row per treatment in creation order (name, environment, stiffness_mpa,
  switch_at (first generation in the second environment, or <NA>), population,
  generations, workspace, cycles, repetitions, seed, algorithm);
- ``runs``: the export's runs table (``service.db.export.runs_frame``) plus ``generation``
  (the last one stored);
- ``generations``: per run and generation, the stored summary (environment, best_distance,
  mean_distance, front_size, evaluations, evaluation_seconds, created_at);
- ``populations``: the populations kept at generation 0 and at each run's last stored
  generation (run_id, generation, individual_id, front_rank), each member with the traits
  of its latest evaluation at or before that generation (after an environment switch: the
  one in the new environment);
- ``evaluations``: every evaluation of those members (the export's individuals columns)
  with ``treatment`` and ``repetition``.

Only the two ends of each run are read: a paper-scale experiment stores tens of millions of
evaluations, and the analyses need the per-generation summaries and the populations at the
start and the end.

Trait columns are ``TRAITS``: distance (voxel lengths), active_share, voxel_count,
frequency (Hz), branching, shape_entropy (bits), symmetry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pandas as pd
from softevo.service.db.export import INDIVIDUAL_COLUMNS, evaluation_rows, runs_frame
from softevo.service.db.models import (
    TRAITS,
    Evaluation,
    Experiment,
    Generation,
    Individual,
    PopulationMember,
    Run,
    Treatment,
)
from sqlalchemy import Connection, Engine, and_, or_, select

from softevo.errors import UserError

TRAIT_LABELS = {
    "distance": "distance (voxel lengths)",
    "best_distance": "best distance (voxel lengths)",
    "active_share": "active share",
    "voxel_count": "voxel count",
    "frequency": "frequency (Hz)",
    "branching": "branching index",
    "shape_entropy": "shape entropy (bits)",
    "symmetry": "symmetry index",
}


@dataclass(frozen=True)
class ExperimentData:
    """Everything the analyses need about one experiment (see the module doc)."""

    experiment: dict[str, Any]
    treatments: pd.DataFrame
    runs: pd.DataFrame
    evaluations: pd.DataFrame
    generations: pd.DataFrame
    populations: pd.DataFrame

    @property
    def treatment_names(self) -> list[str]:
        """Treatment names in creation order."""
        return list(self.treatments["name"])

    def final_populations(self) -> pd.DataFrame:
        """Members of each run's population at its last stored generation."""
        last = self.populations["run_id"].map(self.runs.set_index("run_id")["generation"])
        return self.populations[self.populations["generation"] == last].reset_index(drop=True)

    def initial_populations(self) -> pd.DataFrame:
        """Members of each run's population at generation 0."""
        return self.populations[self.populations["generation"] == 0].reset_index(drop=True)


def load_experiment(engine: Engine, experiment_id: int) -> ExperimentData:
    """Read experiment ``experiment_id`` (UserError if it does not exist or has no runs)."""
    with engine.connect() as conn:
        experiment = _experiment_row(conn, experiment_id)
        treatments = _treatments_frame(conn, experiment_id)
        run_ids = _run_ids(conn, experiment_id)
        if not run_ids:
            raise UserError(f"experiment e{experiment_id} has no runs")
        runs = _with_last_generation(conn, runs_frame(conn, run_ids))
        generations = _generations_frame(conn, run_ids)
        members = _end_members(conn, run_ids)
        evaluations = _member_evaluations(conn, run_ids)
    labels = runs[["run_id", "treatment", "repetition"]]
    evaluations = evaluations.merge(labels, on="run_id", how="left")
    generations = generations.merge(labels, on="run_id", how="left")
    populations = _member_traits(members, evaluations).merge(labels, on="run_id", how="left")
    return ExperimentData(experiment, treatments, runs, evaluations, generations, populations)


def _experiment_row(conn: Connection, experiment_id: int) -> dict[str, Any]:
    table = Experiment.__table__
    row = conn.execute(select(table).where(table.c.id == experiment_id)).mappings().first()
    if row is None:
        raise UserError(f"no experiment e{experiment_id} (see `softevo status`)")
    return dict(row)


def _treatments_frame(conn: Connection, experiment_id: int) -> pd.DataFrame:
    from softevo.service.treatments import Treatment as Settings

    table = Treatment.__table__
    rows = conn.execute(
        select(table.c.name, table.c.settings)
        .where(table.c.experiment_id == experiment_id)
        .order_by(table.c.id)
    ).all()
    records = []
    for name, settings in rows:
        treatment = Settings.from_settings(settings)
        record = treatment.to_settings()
        record["name"] = name
        record["switch_at"] = treatment.switch_generation()
        record["schedule"] = treatment.schedule_text()
        record["workspace"] = "x".join(str(n) for n in treatment.workspace)
        records.append(record)
    frame = pd.DataFrame.from_records(records)
    if not frame.empty:
        frame["switch_at"] = frame["switch_at"].astype("Int64")
    return frame


def _run_ids(conn: Connection, experiment_id: int) -> list[int]:
    runs, treatments = Run.__table__, Treatment.__table__
    query = (
        select(runs.c.id)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(treatments.c.experiment_id == experiment_id)
        .order_by(runs.c.id)
    )
    return [int(i) for i in conn.execute(query).scalars()]


def _with_last_generation(conn: Connection, runs: pd.DataFrame) -> pd.DataFrame:
    table = Run.__table__
    rows = conn.execute(
        select(table.c.id.label("run_id"), table.c.generation.label("generation")).where(
            table.c.id.in_([int(i) for i in runs["run_id"]])
        )
    ).all()
    last = pd.DataFrame(rows, columns=["run_id", "generation"])
    return runs.merge(last, on="run_id", how="left")


def _end_member_filter(run_ids: list[int]):
    """WHERE clause: population rows of ``run_ids`` at generation 0 or the run's last one."""
    members, runs = PopulationMember.__table__, Run.__table__
    return and_(
        members.c.run_id.in_(run_ids),
        or_(members.c.generation == 0, members.c.generation == runs.c.generation),
    )


def _end_members(conn: Connection, run_ids: list[int]) -> pd.DataFrame:
    """Population rows (run_id, generation, individual_id, front_rank) of the initial and the
    last stored generation of each run."""
    members, runs = PopulationMember.__table__, Run.__table__
    columns = ["run_id", "generation", "individual_id", "front_rank"]
    result = conn.execute(
        select(*[members.c[name] for name in columns])
        .join(runs, members.c.run_id == runs.c.id)
        .where(_end_member_filter(run_ids))
        .order_by(members.c.run_id, members.c.generation, members.c.front_rank, members.c.individual_id)
    )
    return pd.DataFrame(result.fetchall(), columns=columns)


def _member_evaluations(conn: Connection, run_ids: list[int]) -> pd.DataFrame:
    """Every evaluation of the individuals in ``_end_members``, with the export's
    individuals columns (``service.db.export.INDIVIDUAL_COLUMNS``)."""
    evaluations = Evaluation.__table__
    members, runs = PopulationMember.__table__, Run.__table__
    wanted = (
        select(members.c.individual_id)
        .join(runs, members.c.run_id == runs.c.id)
        .where(_end_member_filter(run_ids))
    )
    result = conn.execute(evaluation_rows(evaluations.c.individual_id.in_(wanted)))
    frame = pd.DataFrame(result.fetchall(), columns=list(result.keys()))
    frame["parent_id"] = frame["parent_id"].astype("Int64")
    return frame[INDIVIDUAL_COLUMNS]


def _generations_frame(conn: Connection, run_ids: list[int]) -> pd.DataFrame:
    table = Generation.__table__
    columns = [
        "run_id",
        "generation",
        "environment",
        "evaluations",
        "best_distance",
        "mean_distance",
        "front_size",
        "evaluation_seconds",
        "created_at",
    ]
    result = conn.execute(
        select(*[table.c[name] for name in columns])
        .where(table.c.run_id.in_(run_ids))
        .order_by(table.c.run_id, table.c.generation)
    )
    return pd.DataFrame(result.fetchall(), columns=columns)


def _member_traits(members: pd.DataFrame, evaluations: pd.DataFrame) -> pd.DataFrame:
    """Members with the traits of their latest evaluation at or before the member's
    generation (``evaluation_generation``, ``environment``, ``stable`` and ``TRAITS``)."""
    traits = evaluations[["individual_id", "generation", "environment", "stable", *TRAITS]]
    traits = traits.rename(columns={"generation": "evaluation_generation"})
    if members.empty:  # nothing stored yet: merge_asof cannot type empty keys
        return pd.DataFrame(columns=[*members.columns, *traits.columns.drop("individual_id")])
    left = members.sort_values("generation", kind="stable").reset_index(drop=True)
    right = traits.sort_values("evaluation_generation", kind="stable").reset_index(drop=True)
    merged = pd.merge_asof(
        left,
        right,
        left_on="generation",
        right_on="evaluation_generation",
        by="individual_id",
        direction="backward",
    )
    return merged.sort_values(["run_id", "generation", "front_rank", "individual_id"]).reset_index(drop=True)


def individual_record(engine: Engine, individual_id: int) -> dict[str, Any]:
    """The stored individual (id, run_id, genome, generation_born, ...), its run's treatment
    (``service.treatments.Treatment``) and seed, and its evaluations (a DataFrame, oldest
    first). UserError if there is no such individual."""
    from softevo.service.db.store import run_row
    from softevo.service.treatments import Treatment as Settings

    table = Individual.__table__
    with engine.connect() as conn:
        row = conn.execute(select(table).where(table.c.id == int(individual_id))).mappings().first()
        if row is None:
            raise UserError(f"no individual {individual_id}")
        run = run_row(conn, row["run_id"])
        evaluations = _evaluations_of(conn, int(individual_id))
    return {
        **dict(row),
        "treatment": Settings.from_settings(run["settings"]),
        "treatment_name": run["treatment"],
        "experiment": run["experiment"],
        "seed": run["seed"],
        "repetition": run["repetition"],
        "evaluations": evaluations,
    }


def _evaluations_of(conn: Connection, individual_id: int) -> pd.DataFrame:
    table = Evaluation.__table__
    columns = ["generation", "age", "environment", "stiffness", *TRAITS, "stable", "error"]
    result = conn.execute(
        select(*[table.c[name] for name in columns])
        .where(table.c.individual_id == individual_id)
        .order_by(table.c.generation)
    )
    return pd.DataFrame(result.fetchall(), columns=columns)
