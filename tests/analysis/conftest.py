"""One real tiny experiment per test session: a static treatment and a transition at the same
stiffness (so every figure, the transition one included, has something to draw), population
4, 3 generations, 3 repetitions (the fewest a test or an interval takes), 2 actuation cycles,
a 4x4x4 workspace; evaluated inline."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest
from sqlalchemy import Engine

from softevo.evolution.treatments import Treatment
from softevo.service.runs.coordinator import Coordinator
from softevo.service.runs.executors import InlineExecutor
from softevo.service.runs.submit import create
from softevo.service.storage import open_database

COMMON = {"population": 4, "generations": 3, "workspace": (4, 4, 4), "cycles": 2, "repetitions": 3}
TREATMENTS = (
    Treatment("land", 0.1, name="land S3", **COMMON),
    Treatment("water-land", 0.1, name="water-land S3", switch_at=2, **COMMON),
)


@dataclass(frozen=True)
class TinyExperiment:
    """The session's experiment: database URL, engine, experiment id and run ids."""

    url: str
    engine: Engine
    experiment_id: int
    run_ids: list[int]


@pytest.fixture(scope="session")
def tiny(tmp_path_factory) -> TinyExperiment:
    path: Path = tmp_path_factory.mktemp("analysis") / "tiny.db"
    url = f"sqlite:///{path}"
    engine = open_database(url)
    experiment_id, run_ids = create(engine, "tiny-analysis", TREATMENTS)
    Coordinator(engine, InlineExecutor()).run(run_ids)
    yield TinyExperiment(url, engine, experiment_id, run_ids)
    engine.dispose()


@pytest.fixture(scope="session")
def tiny_data(tiny):
    from softevo.service.reports.data import load_experiment

    return load_experiment(tiny.engine, tiny.experiment_id)
