"""Stored individuals back to robots: genome -> phenotype -> scene, exactly as the workers
built them (same encoding, cycles, model, world and stiffness as the evaluation replayed).

The functions take a stored record (``service.storage.individuals.individual_record``: the
individual, its treatment, seed and evaluations; the caller reads it) and go through
``worker.tasks``, the path the evaluations took. ``stored_task(record)`` is the one way from
a stored individual to a ``Task``: the task of its latest evaluation, as the coordinator built
it (the REST frames and body, the report, ``softevo show`` and ``export-vxa`` all replay it);
``record_scene(record)`` is its scene.
"""

from __future__ import annotations

from typing import Any

from softevo.errors import UserError
from softevo.evolution import environments
from softevo.evolution.genotype import Genotype, Phenotype, develop
from softevo.worker.tasks import EmptyBody, Task, scene_of


def develop_genome(genome: dict[str, Any], treatment) -> Phenotype:
    """The phenotype of a stored genome (``Genotype.to_dict()`` JSON) in the encoding of its
    run's ``treatment`` (a ``Treatment``: ``to_settings()``)."""
    return develop(Genotype.from_dict(genome), treatment.encoding)


def stored_evaluation(record: dict[str, Any], environment: str | None = None) -> dict[str, Any]:
    """The record's latest evaluation ({column: value}), its latest in ``environment`` if
    given; UserError if ``environment`` is not an evolvable world or there is no such
    evaluation."""
    individual_id, evaluations = record["id"], record["evaluations"]
    if environment is not None:
        evolvable = environments.names(evolve=True)
        if environment not in evolvable:
            raise UserError(f"environment must be {' or '.join(evolvable)} (got {environment!r})")
        evaluations = evaluations[evaluations["environment"] == environment]
    if evaluations.empty:
        where = f" in {environment}" if environment is not None else ""
        raise UserError(f"individual {individual_id} was never evaluated{where}")
    return evaluations.iloc[-1].to_dict()


def stored_task(record: dict[str, Any], environment: str | None = None, elsewhere: bool = False) -> Task:
    """The ``worker.tasks.Task`` of the record's latest evaluation (in ``environment`` if
    given), as the coordinator built it: that evaluation's world and Young's modulus (a run
    whose stiffness changed replays what was evaluated), its treatment's encoding, cycles,
    model and cap on seconds. UserError as ``stored_evaluation``, except that with
    ``elsewhere`` an individual never evaluated in ``environment`` is put there at its latest
    evaluation's stiffness (a replay evolution never ran: ``softevo show`` and ``export-vxa``
    with ``--environment``; its stored distance is None)."""
    try:
        evaluation = stored_evaluation(record, environment)
    except UserError:
        if not (elsewhere and environment in environments.names(evolve=True)):
            raise
        evaluation = {**stored_evaluation(record), "environment": environment}
    return Task.from_stored(
        record["id"],
        record["genome"],
        record["treatment"].to_settings(),
        str(evaluation["environment"]),
        float(evaluation["stiffness"]),
    )


def stored_distance(record: dict[str, Any], environment: str) -> float | None:
    """The distance of the record's latest evaluation in ``environment`` (None if none)."""
    evaluations = record["evaluations"]
    same = evaluations[evaluations["environment"] == environment]
    return float(same["distance"].iloc[-1]) if not same.empty else None


def record_scene(
    record: dict[str, Any], environment: str | None = None, **extra: Any
) -> tuple[dict[str, Any], dict[str, Any]]:
    """(scene, record) of a stored record, ready for ``sim.simulate``.

    ``environment`` defaults to that of the individual's latest evaluation. ``extra`` scene
    fields (e.g. ``record``) are added. The record returned is the one given plus
    ``phenotype_object``, ``environment`` (the one used) and ``task``. UserError for an empty
    body or a compound world (a gradual transition's evaluation is several scenes). An
    ``environment`` it was never evaluated in replays it there (``stored_task``'s
    ``elsewhere``).
    """
    task = stored_task(record, environment, elsewhere=True)
    if environments.is_compound(task.environment):
        raise UserError(
            f"individual {record['id']} was last evaluated in {task.environment}, a world of "
            "several scenes; give --environment"
        )
    try:
        phenotype, scene = scene_of(task, **extra)
    except EmptyBody as exc:
        raise UserError(f"individual {record['id']} has an empty body: nothing to simulate") from exc
    return scene, {**record, "phenotype_object": phenotype, "environment": task.environment, "task": task}
