"""Stored individuals back to robots: genome -> phenotype -> scene, exactly as the workers
built them (same encoding, stiffness and cycles as the individual's run).

The functions take a stored record (``service.db.individuals.individual_record``: the
individual, its treatment's settings, seed and evaluations; the caller reads it) and go
through ``worker.tasks``, the path the evaluations took: ``stored_task(record)`` is the task
of its latest evaluation, ``record_scene(record)`` its scene.
"""

from __future__ import annotations

from typing import Any

from softevo.errors import UserError
from softevo.evolution import worlds
from softevo.evolution.genotype import EncodingConfig, Genotype, Phenotype, develop
from softevo.worker.tasks import Task, scene_of
from softevo.worker.tasks import encoding_of as settings_encoding


def encoding_of(treatment, seed: int = 0) -> EncodingConfig:
    """The encoding the run of ``treatment`` (a ``Treatment``: ``to_settings()``) expressed
    its genomes with (the same for every seed)."""
    return settings_encoding(treatment.to_settings())


def develop_genome(genome: dict[str, Any], treatment, seed: int = 0) -> Phenotype:
    """The phenotype of a stored genome (``Genotype.to_dict()`` JSON) in its run's encoding."""
    return develop(Genotype.from_dict(genome), encoding_of(treatment, seed))


def record_environment(record: dict[str, Any], environment: str | None = None) -> str:
    """``environment``, or that of the record's latest evaluation (after an environment
    switch, the new one); UserError if there is none or it is unknown."""
    individual_id, evaluations = record["id"], record["evaluations"]
    if environment is None:
        if evaluations.empty:
            raise UserError(f"individual {individual_id} was never evaluated; give --environment")
        environment = str(evaluations["environment"].iloc[-1])
    if environment not in worlds.names(evolve=True):
        raise UserError(f"environment must be {' or '.join(worlds.names(evolve=True))} (got {environment!r})")
    return environment


def stored_task(record: dict[str, Any], environment: str | None = None) -> Task:
    """The ``worker.tasks.Task`` of a stored record in ``environment`` (default: that of its
    latest evaluation), with its treatment's stiffness and cycles."""
    treatment = record["treatment"]
    return Task.from_stored(
        record["id"],
        record["genome"],
        treatment.to_settings(),
        record_environment(record, environment),
        treatment.stiffness_pa,
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
    ``phenotype_object``, ``environment`` (the one used) and ``task``.
    """
    task = stored_task(record, environment)
    try:
        phenotype, scene = scene_of(task, **extra)
    except ValueError as exc:
        if str(exc) != "empty body":
            raise
        raise UserError(f"individual {record['id']} has an empty body: nothing to simulate") from exc
    return scene, {**record, "phenotype_object": phenotype, "environment": task.environment, "task": task}

