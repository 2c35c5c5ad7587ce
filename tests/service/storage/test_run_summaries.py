"""Run summaries (``softevo status``, ``GET /runs``, the experiments' run pages): the world and
best distance of the last generation, and the best reached in each world (issue 28, item 2)."""

from __future__ import annotations

import dataclasses

from softevo.service.api.schemas import RunSummary
from softevo.service.storage.experiments import NewRun, NewTreatment, create_experiment, list_experiments
from softevo.service.storage.generations import record_generation
from softevo.service.storage.runs import list_runs
from softevo.service.storage.status import run_summaries
from tests.service import handbuilt
from tests.support import softevo

# a land -> water run whose generation-0 land walker outdoes every water robot
BEST = {0: 5.207, 1: 4.0, 2: 0.33, 3: 0.65}


def _land_walker_run(engine) -> int:
    with engine.begin() as conn:
        _, (run_id,) = create_experiment(
            conn, "lw", [NewTreatment("lw", handbuilt.TREATMENT.to_settings(), [NewRun(0, 7, 4)])]
        )
    for generation, best in BEST.items():
        record = handbuilt.generation_record(run_id, generation)
        summary = {**record.summary, "best_distance": best}
        with engine.begin() as conn:
            record_generation(conn, dataclasses.replace(record, summary=summary))
    return run_id


def test_summaries_give_the_last_generation_and_the_best_per_world(engine):
    run_id = _land_walker_run(engine)
    (summary,) = run_summaries(engine, [run_id])
    assert summary["environment"] == "water" and summary["best_distance"] == 0.65
    assert summary["best_by_world"] == {"land": 5.207, "water": 0.65}
    with engine.connect() as conn:
        (listed,) = list_runs(conn)
        (experiment,) = list_experiments(conn)
    for row in (listed, experiment["runs"][0]):
        run = RunSummary.model_validate(row)
        assert run.best_distance == 0.65 and run.best_by_world == {"land": 5.207, "water": 0.65}
        assert list(run.best_by_world) == ["land", "water"]


def test_a_run_without_generations_has_no_best(engine):
    with engine.begin() as conn:
        _, (run_id,) = create_experiment(
            conn, "new", [NewTreatment("lw", handbuilt.TREATMENT.to_settings(), [NewRun(0, 7, 4)])]
        )
    (summary,) = run_summaries(engine, [run_id])
    assert summary["best_distance"] is None and summary["environment"] is None
    assert summary["best_by_world"] == {}


def test_status_prints_the_best_per_world(capsys, engine, db_url):
    _land_walker_run(engine)
    code, out, err = softevo(capsys, "status", "--db", db_url)
    assert code == 0, err
    row, second = [line.split() for line in out.splitlines() if "land" in line or "water" in line][:2]
    assert row[-4:] == ["water", "0.650", "land", "5.207"] and second == ["water", "0.650"]
