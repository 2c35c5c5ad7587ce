"""Export: the CSV files of docs/spec.md section 7, readable with pandas."""

from __future__ import annotations

import builtins

import pandas as pd
import pytest

from softevo.errors import UserError
from softevo.evolution.treatments import Treatment
from softevo.service.runs.coordinator import Coordinator
from softevo.service.runs.executors import InlineExecutor
from softevo.service.runs.submit import create
from softevo.service.storage import open_database
from softevo.service.storage.export import (
    COST_COLUMNS,
    POPULATION_COLUMNS,
    RUN_COLUMNS,
    export_runs,
    individual_columns,
    individuals_frame,
)
from tests.service import handbuilt


def test_csv_export(engine, tmp_path):
    run_id = handbuilt.build(engine)
    paths = export_runs(engine, [run_id], tmp_path / "out")
    assert sorted(p.name for p in paths) == ["individuals.csv", "populations.csv", "runs.csv"]
    runs = pd.read_csv(tmp_path / "out" / "runs.csv")
    individuals = pd.read_csv(tmp_path / "out" / "individuals.csv")
    populations = pd.read_csv(tmp_path / "out" / "populations.csv")
    assert list(runs.columns) == RUN_COLUMNS
    assert list(individuals.columns) == individual_columns()
    assert list(populations.columns) == POPULATION_COLUMNS
    row = runs.iloc[0]
    assert row["environment_schedule"] == "land:0,water:2"
    assert row["stiffness_pa"] == 1e5 and row["population"] == 3 and row["status"] == "finished"
    # the evaluation's protocol travels with the data: a reader recomputes what the guard cut
    assert row["switch_at"] == 2 and row["settle_seconds"] == "land:0.5,water:0"
    assert row["cycles"] >= 1 and row["model"] in ("voxelyze-2", "voxcad-land-water")
    assert row["control_mapping"] and row["algorithm"] in ("afpo", "pareto")
    assert row["generations"] == 4 and row["generations_run"] == 4  # planned, stored
    assert len(individuals) == 15  # 12 births + 3 re-evaluations at the switch
    # newcomers 1, 2, 3, 6, 9, 12; newcomer 1 was evaluated twice (land, then water)
    assert individuals["parent_id"].isna().sum() == 7
    assert len(populations) == 12 and populations["front_rank"].min() == 0
    failed = individuals[individuals["error"].notna()]
    assert list(failed["stable"]) == [False]
    # hand-built evaluations have wall seconds only: their steps were never stored
    assert set(individuals["wall_seconds"]) == {0.01}
    assert individuals[["steps", "simulated_seconds"]].isna().all().all()


@pytest.fixture(scope="module")
def tiny_runs(tmp_path_factory):
    """Three repetitions of a tiny land -> water treatment, run for real (inline): the first
    to its end, the second for one generation, the third not at all."""
    engine = open_database(f"sqlite:///{tmp_path_factory.mktemp('export') / 'tiny.db'}")
    treatment = Treatment("land-water", 0.1, population=3, generations=3, switch_at=2, workspace=(4, 4, 4),
                          cycles=2, seed=11, repetitions=3)
    _, run_ids = create(engine, "tiny", [treatment])
    Coordinator(engine, InlineExecutor()).run(run_ids[:1])
    Coordinator(engine, InlineExecutor()).run(run_ids[1:2], max_rounds=1)
    yield engine, run_ids, treatment
    engine.dispose()


def test_runs_say_the_generations_planned_and_run(tiny_runs, tmp_path):
    engine, run_ids, _ = tiny_runs
    export_runs(engine, run_ids, tmp_path)
    runs = pd.read_csv(tmp_path / "runs.csv")
    assert list(runs.columns) == RUN_COLUMNS
    assert list(runs["generations"]) == [3, 3, 3]
    assert list(runs["generations_run"]) == [3, 1, 0]
    assert runs["status"].iloc[0] == "finished" and runs["status"].iloc[2] == "pending"


def test_individuals_of_a_real_run_say_what_each_evaluation_cost(tiny_runs, tmp_path):
    engine, run_ids, treatment = tiny_runs
    export_runs(engine, run_ids[:1], tmp_path)
    individuals = pd.read_csv(tmp_path / "individuals.csv")
    assert list(individuals.columns[-3:]) == COST_COLUMNS == ["steps", "simulated_seconds", "wall_seconds"]
    simulated = individuals[individuals["active_share"] > 0]  # a passive body is not simulated
    assert len(simulated) >= 3 and simulated[COST_COLUMNS].notna().all().all()
    passive = individuals[individuals["active_share"] == 0]
    assert passive[COST_COLUMNS].isna().all().all()
    assert (simulated["steps"] > 0).all() and (simulated["wall_seconds"] > 0).all()
    with engine.connect() as conn:
        assert str(individuals_frame(conn, run_ids[:1])["steps"].dtype) == "Int64"  # whole steps
    # uncapped: the world's settling (0.5 s on land, none in water), then 2 cycles at the robot's f
    settle = simulated["environment"].map(treatment.settle_seconds())
    expected = settle + 2 / simulated["frequency"]
    assert set(simulated["environment"]) == {"land", "water"}
    assert list(simulated["simulated_seconds"]) == pytest.approx(list(expected), rel=1e-3)


def test_parquet_without_pyarrow_is_a_clear_error(engine, tmp_path, monkeypatch):
    real_import = builtins.__import__

    def no_pyarrow(name, *args, **kwargs):
        if name == "pyarrow":
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_pyarrow)
    with pytest.raises(UserError, match="pyarrow"):
        export_runs(engine, [1], tmp_path, fmt="parquet")


def test_parquet_export(engine, tmp_path):
    pytest.importorskip("pyarrow")
    run_id = handbuilt.build(engine)
    export_runs(engine, [run_id], tmp_path, fmt="parquet")
    assert len(pd.read_parquet(tmp_path / "individuals.parquet")) == 15


def test_unknown_format(engine, tmp_path):
    with pytest.raises(UserError, match="unknown format"):
        export_runs(engine, [1], tmp_path, fmt="xlsx")
