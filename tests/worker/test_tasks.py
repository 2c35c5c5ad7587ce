"""worker.tasks: the wire format, the failed result, and that a stored individual's scene and
replay are the ones its evaluation simulated."""

from __future__ import annotations

import json

import numpy as np
import pytest

from softevo import sim
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import EncodingConfig, random_viable_genotype
from softevo.evolution.outcome import FAILED_DISTANCE, Outcome
from softevo.worker import evaluate
from softevo.worker.tasks import RESULT_KEYS, Task, TaskResult, failed, json_ready, replay, scene_of

ENCODING = EncodingConfig(workspace=(4, 4, 4))


def _task(model: str = "voxelyze-2", max_seconds: float | None = None, **extra) -> Task:
    genome = random_viable_genotype(np.random.default_rng(3), ENCODING)
    spec = EvaluationSpec("land", 1e5, 2, model=model, max_seconds=max_seconds, encoding=ENCODING)
    return Task.from_genome(genome, spec, id=7, **extra)


def test_task_json_is_the_wire_format_and_round_trips_exactly():
    task = _task(run_id=2, generation=5)
    data = task.to_json()
    assert list(data) == [
        "id", "run_id", "generation", "genome", "environment", "youngs_modulus", "cycles", "workspace",
        "encoding",
    ]  # fmt: skip
    assert data["workspace"] == [4, 4, 4] and data["encoding"] == ENCODING.to_dict()
    wire = json.loads(json.dumps(data))
    assert Task.from_json(wire) == task
    assert Task.from_json(wire).to_json() == wire
    old = {k: v for k, v in wire.items() if k not in ("run_id", "generation", "encoding")}
    # a task with a workspace only (an older coordinator's) reads with the default encoding
    assert Task.from_json(old).to_json() == {**old, "encoding": ENCODING.to_dict()}
    assert Task.from_json(old).evaluation.encoding == ENCODING


def test_result_json_round_trips_exactly():
    result = evaluate.evaluate_batch([_task().to_json()], threads=1)[0]
    assert list(result) == list(RESULT_KEYS)
    wire = json.loads(json.dumps(result))
    assert TaskResult.from_json(wire).to_json() == wire


def test_failed_is_the_worst_fitness_with_the_reason():
    for task in (_task(), _task().to_json(), {"id": 7}):
        result = failed(task, "boom")
        assert result.id == 7 and result.outcome.distance == FAILED_DISTANCE
        assert not result.outcome.stable and result.outcome.error == "boom" and not result.outcome.ok
        assert result.to_json() == {
            "id": 7, "distance": FAILED_DISTANCE, "stable": False, "error": "boom", "voxel_count": 0,
            "active_share": 0.0, "frequency": None, "descriptors": None, "phenotype": None, "seconds": 0.0,
            "steps": 0, "simulated_seconds": 0.0,
        }  # fmt: skip


def test_nan_or_unstable_scores_the_failed_distance():
    task = _task()
    phenotype, _ = scene_of(task)
    nan = Outcome.of_simulation(float("nan"), True)
    unstable = Outcome.of_simulation(3.0, False, "diverged")
    for outcome, error in ((nan, "non-finite distance"), (unstable, "diverged")):
        result = TaskResult.of(task, outcome, phenotype, 0.1).outcome
        assert (result.distance, result.stable, result.error) == (FAILED_DISTANCE, False, error)


@pytest.mark.parametrize("max_seconds", [None, 0.2])
def test_a_result_carries_the_steps_and_simulated_seconds_it_cost(max_seconds):
    """steps: the engine's step count of the scene (settling included); simulated_seconds:
    those steps at the scene's dt, the settling plus ``cycles / f`` when the guard on seconds
    does not bind, the settling plus the guard when it does."""
    task = _task(max_seconds=max_seconds)
    (result,) = evaluate.evaluate_batch([task.to_json()], threads=1)
    _, scene = scene_of(task)
    parsed = sim.parse_scene(scene)
    assert result["stable"] and isinstance(result["steps"], int)
    assert result["steps"] == sim.scene_steps(parsed) > 0
    assert result["simulated_seconds"] == pytest.approx(result["steps"] * sim.scene_dt(parsed), rel=1e-6)
    settle, actuated = scene["settle_seconds"], task.evaluation.cycles / result["frequency"]
    if max_seconds is None:
        assert result["simulated_seconds"] >= settle + actuated - sim.scene_dt(parsed)
        assert result["simulated_seconds"] == pytest.approx(settle + actuated, rel=1e-3)
    else:
        assert actuated > max_seconds
        assert result["simulated_seconds"] == pytest.approx(settle + max_seconds, rel=1e-3)
    assert result["seconds"] > 0  # the wall seconds, apart from the simulated ones


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """A tiny land->water run evaluated inline, with every scene the evaluation simulated."""
    from softevo.evolution.treatments import Treatment
    from softevo.service.runs.coordinator import Coordinator
    from softevo.service.runs.executors import InlineExecutor
    from softevo.service.runs.submit import create
    from softevo.service.storage import open_database

    treatment = Treatment(
        "land-water", 0.1, population=3, generations=3, switch_at=2, workspace=(4, 4, 4), cycles=2, seed=5
    )
    engine = open_database(f"sqlite:///{tmp_path_factory.mktemp('tasks') / 'tasks.db'}")
    _, (run_id,) = create(engine, "tasks", [treatment])
    simulated = {}
    real = evaluate.scenes_of

    def recording(task, **options):
        phenotype, scenes = real(task, **options)
        (simulated[(task.id, task.generation)],) = json_ready(scenes)  # pure worlds: one scene
        return phenotype, scenes

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(evaluate, "scenes_of", recording)
        Coordinator(engine, InlineExecutor()).run([run_id])
    yield engine, run_id, simulated
    engine.dispose()


def _stored_evaluations(engine, run_id):
    from sqlalchemy import select

    from softevo.service.storage.models import EvaluationRow, IndividualRow

    ind, ev = IndividualRow.__table__, EvaluationRow.__table__
    query = (
        select(ind.c.id, ind.c.local_id, ind.c.genome, ev.c.generation, ev.c.environment, ev.c.stiffness,
               ev.c.distance, ev.c.stable)
        .join(ind, ev.c.individual_id == ind.c.id)
        .where(ev.c.run_id == run_id, ev.c.stable.is_(True))
        .order_by(ev.c.generation, ind.c.local_id)
    )  # fmt: skip
    with engine.connect() as conn:
        return conn.execute(query).mappings().all()


def _task_of(engine, row) -> Task:
    from softevo.service.storage.individuals import individual_record

    settings = individual_record(engine, row["id"]).get("treatment").to_settings()
    return Task.from_stored(row["id"], row["genome"], settings, row["environment"], row["stiffness"])


def test_the_scene_of_a_stored_genome_is_the_one_evaluated(stored):
    engine, run_id, simulated = stored
    rows = _stored_evaluations(engine, run_id)
    assert {row["environment"] for row in rows} == {"land", "water"}
    compared = 0
    for row in rows:
        key = (row["local_id"], row["generation"])
        if key in simulated:  # evaluated in that generation (not carried over)
            _, scene = scene_of(_task_of(engine, row))
            assert json_ready(scene) == simulated[key]
            compared += 1
    assert compared >= 3


def test_stored_evaluations_keep_what_they_cost(stored):
    """The coordinator stores each evaluation's steps and simulated seconds: those of the
    scene it simulated."""
    from sqlalchemy import select

    from softevo.service.storage.models import EvaluationRow, IndividualRow

    engine, run_id, simulated = stored
    ind, ev = IndividualRow.__table__, EvaluationRow.__table__
    query = (
        select(ind.c.local_id, ev.c.generation, ev.c.steps, ev.c.simulated_seconds, ev.c.seconds)
        .join(ind, ev.c.individual_id == ind.c.id)
        .where(ev.c.run_id == run_id)
    )
    with engine.connect() as conn:
        rows = {(row.local_id, row.generation): row for row in conn.execute(query)}
    compared = 0
    for key, scene in simulated.items():
        parsed = sim.parse_scene(scene)
        row = rows[key]
        assert row.steps == sim.scene_steps(parsed) > 0 and row.seconds is not None
        assert row.simulated_seconds == pytest.approx(row.steps * sim.scene_dt(parsed), rel=1e-6)
        compared += 1
    assert compared >= 3


def test_replay_gives_the_evaluated_distance(stored):
    engine, run_id, _ = stored
    row = max(_stored_evaluations(engine, run_id), key=lambda r: r["distance"])
    motion = replay(_task_of(engine, row), every=50, max_frames=20)
    assert float(motion["distance"]) == pytest.approx(row["distance"], rel=1e-9, abs=1e-12)
    assert bool(motion["stable"]) and len(motion["t"]) == 20
    assert motion["positions"].shape == (20, len(motion["voxels"]), 3)
    assert set(np.unique(motion["material"])) <= {1, 2}
