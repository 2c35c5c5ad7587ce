"""Objectives as data: an objective registered in ``evolution.selection`` (no migration, no
new column) is computed by the evolution loop, used by selection, stored with every
evaluation, served by the REST API and shown in the report of a real tiny run; and migration
0002 gives the evaluations of a database made at 0001 their objectives."""

from __future__ import annotations

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient

from softevo.evolution.algorithm import Evolution
from softevo.evolution.selection import (
    OBJECTIVES,
    Objective,
    non_dominated_sort,
    objective_matrix,
    register_objective,
    unregister_objective,
)
from softevo.service.api.app import create_app
from softevo.service.reports.report import write_report
from softevo.service.runs.coordinator import Coordinator
from softevo.service.runs.executors import InlineExecutor
from softevo.service.settings import Settings
from softevo.service.storage import make_engine, open_database
from softevo.service.storage.individuals import individual
from softevo.service.storage.migrate import upgrade
from softevo.service.storage.models import EvaluationRow, PopulationMemberRow, RunRow
from tests.service.old_schema import store_one_evaluation

TOY = "voxel_count_squared"
TOKEN = "objectives-test-token"


@pytest.fixture
def toy_objective():
    """A toy objective, minimise the voxel count squared, registered for one test only."""
    objective = register_objective(
        Objective(TOY, "min", lambda evaluation, phenotype: float(phenotype.voxel_count) ** 2)
    )
    yield objective
    unregister_objective(TOY)
    assert TOY not in OBJECTIVES


def test_a_registered_objective_flows_through_a_real_run(toy_objective, tmp_path):
    url = f"sqlite:///{tmp_path / 'toy.db'}"
    open_database(url).dispose()
    settings = Settings(db=url, token=TOKEN, coordinator=False, workers=0, reports=str(tmp_path / "reports"))
    treatment = {"environment": "land", "stiffness_mpa": 0.1, "population": 4, "generations": 3,
                 "workspace": [4, 4, 4], "cycles": 2, "objectives": ["distance", TOY]}
    with TestClient(create_app(settings)) as client:
        created = client.post("/experiments", json={"name": "toy", "treatments": [treatment]},
                              headers={"Authorization": f"Bearer {TOKEN}"})
        assert created.status_code == 201, created.text
        experiment_id, (run_id,) = created.json()["id"], created.json()["runs"]

        engine = open_database(url)
        Coordinator(engine, InlineExecutor()).run([run_id])

        # selection: the run's algorithm selects on the toy objective (plus age, afpo)
        with engine.connect() as conn:
            state = conn.execute(sa.select(RunRow.__table__.c.algorithm_state)).scalar_one()
            last = conn.execute(sa.select(RunRow.__table__.c.generation)).scalar_one()
            stored = conn.execute(sa.select(EvaluationRow.__table__.c.objectives,
                                            EvaluationRow.__table__.c.voxel_count)).all()
            pm = PopulationMemberRow.__table__
            members = conn.execute(
                sa.select(pm.c.individual_id, pm.c.front_rank)
                .where(pm.c.generation == last)
                .order_by(pm.c.individual_id)
            ).all()
        algo = Evolution.from_state_dict(state)
        assert [o.name for o in algo.config.selection_objectives] == ["distance", TOY, "age"]
        assert algo.config.objectives[1] is toy_objective
        # stored: every evaluation holds the toy objective, computed from its phenotype
        assert stored and all(set(o) == {"distance", TOY} for o, _ in stored)
        assert all(o[TOY] == float(count) ** 2 for o, count in stored)
        # the stored front ranks are those over the run's objectives, the toy one included
        population = [ind for ind in algo.population if not ind.failed]
        matrix = objective_matrix([i.objectives for i in population], algo.config.objectives)
        ranks = non_dominated_sort(matrix)
        by_local = dict(zip([i.id for i in population], ranks, strict=True))
        with engine.connect() as conn:
            local = {i: individual(conn, i)["local_id"] for i, _ in members}
        assert [rank for i, rank in members if local[i] in by_local] == [
            by_local[local[i]] for i, _ in members if local[i] in by_local]

        # served: the front and an individual carry the toy objective
        front = client.get(f"/runs/{run_id}/front").json()
        assert front["individuals"] and all(TOY in m["objectives"] for m in front["individuals"])
        assert all(TOY in m["evaluation"]["objectives"] for m in front["individuals"])
        one = client.get(f"/individuals/{members[0][0]}").json()
        assert one["objectives"][TOY] == float(one["phenotype"]["voxel_count"]) ** 2
        engine.dispose()

    # shown: the report's objectives table names it, minimised, with its values
    with pytest.warns(Warning, match="fewer than 3 runs"):  # one repetition: enough to show the table
        report = write_report(url, experiment_id, tmp_path / "report", animation=False, progress=False)
    text = report.markdown.read_text(encoding="utf-8")
    assert "## Objectives" in text and TOY in text and "minimised" in text
    assert "active_share" not in text.split("## Objectives")[1].split("##")[0]


def test_an_unregistered_objective_is_refused_and_its_runs_still_read(toy_objective, tmp_path):
    """A new experiment may only name registered objectives; one stored with an objective no
    longer registered still reads (its settings, its report), it only cannot run."""
    from softevo.errors import UserError
    from softevo.evolution.treatments import Treatment
    from softevo.service.runs.submit import create

    engine = open_database(f"sqlite:///{tmp_path / 'old.db'}")
    with pytest.raises(UserError, match="unknown objective 'height'"):
        create(engine, "x", [Treatment("land", 0.1, objectives=("distance", "height"))])
    toy = Treatment("land", 0.1, objectives=("distance", TOY))
    create(engine, "toy", [toy])
    unregister_objective(TOY)
    try:
        stored = Treatment.from_settings(toy.to_settings())
        assert stored.objectives == ("distance", TOY)
        with pytest.raises(UserError, match=f"unknown objective '{TOY}'"):
            stored.evolution_config(0)
    finally:
        register_objective(toy_objective)
    engine.dispose()
    with pytest.raises(UserError, match="must include distance"):
        Treatment("land", 0.1, objectives=("active_share",))
    assert "objectives" not in Treatment("land", 0.1).to_settings()


def test_migration_0002_gives_stored_evaluations_their_objectives(db_url):
    """A database made at 0001, holding an evaluation, upgraded to the head: the evaluation's
    objectives are its three columns, and the API's reader gives them."""
    engine = make_engine(db_url)
    upgrade(engine, "0001")
    meta = sa.MetaData()
    meta.reflect(engine)
    assert "objectives" not in meta.tables["evaluations"].c
    store_one_evaluation(engine)
    upgrade(engine)
    with engine.connect() as conn:
        stored = conn.execute(sa.select(EvaluationRow.__table__.c.objectives)).scalar_one()
        assert stored == {"distance": 2.5, "active_share": 0.25, "voxel_count": 12}
        assert individual(conn, 1)["objectives"] == stored
    engine.dispose()
