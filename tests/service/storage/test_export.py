"""Export: the CSV files of docs/spec.md section 7, readable with pandas."""

from __future__ import annotations

import builtins

import pandas as pd
import pytest

from softevo.errors import UserError
from softevo.service.storage.export import (
    POPULATION_COLUMNS,
    RUN_COLUMNS,
    export_runs,
    individual_columns,
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
    assert len(individuals) == 15  # 12 births + 3 re-evaluations at the switch
    # newcomers 1, 2, 3, 6, 9, 12; newcomer 1 was evaluated twice (land, then water)
    assert individuals["parent_id"].isna().sum() == 7
    assert len(populations) == 12 and populations["front_rank"].min() == 0
    failed = individuals[individuals["error"].notna()]
    assert list(failed["stable"]) == [False]


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
