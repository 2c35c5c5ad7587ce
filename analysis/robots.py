"""Stored individuals back to robots: genome -> phenotype -> scene, exactly as the workers
built them (same encoding, stiffness and cycles as the individual's run).

The encoding is the one the coordinator gives the algorithm
(``service.experiments.evolution_config(treatment, seed).encoding``), so a re-developed
phenotype is the phenotype that was evaluated.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from softevo.evolution.genotype import EncodingConfig, Genotype, Phenotype, develop
from softevo.service.db.individuals import individual_record
from softevo.service.db.models import Individual, Run, Treatment
from softevo.service.treatments import Treatment as Settings
from sqlalchemy import Engine, select

from softevo.errors import UserError


def encoding_of(treatment: Settings, seed: int = 0) -> EncodingConfig:
    """The encoding the run of ``treatment`` expressed its genomes with."""
    from softevo.service.experiments import evolution_config

    return evolution_config(treatment, seed).encoding


def develop_genome(genome: dict[str, Any], treatment: Settings, seed: int = 0) -> Phenotype:
    """The phenotype of a stored genome (``Genotype.to_dict()`` JSON) in its run's encoding."""
    return develop(Genotype.from_dict(genome), encoding_of(treatment, seed))


def phenotypes(engine: Engine, individual_ids: Iterable[int]) -> dict[int, Phenotype]:
    """Phenotypes of many stored individuals in one query (unknown ids are left out)."""
    ids = sorted({int(i) for i in individual_ids})
    if not ids:
        return {}
    individuals, runs, treatments = Individual.__table__, Run.__table__, Treatment.__table__
    query = (
        select(individuals.c.id, individuals.c.genome, treatments.c.settings, runs.c.seed)
        .join(runs, individuals.c.run_id == runs.c.id)
        .join(treatments, runs.c.treatment_id == treatments.c.id)
        .where(individuals.c.id.in_(ids))
    )
    with engine.connect() as conn:
        rows = conn.execute(query).all()
    return {
        int(i): develop_genome(genome, Settings.from_settings(settings), seed)
        for i, genome, settings, seed in rows
    }


def individual_scene(
    engine: Engine, individual_id: int, environment: str | None = None, **extra: Any
) -> tuple[dict[str, Any], dict[str, Any]]:
    """(scene, record) of a stored individual, ready for ``sim.simulate``.

    ``environment`` defaults to that of the individual's latest evaluation (after an
    environment switch, the new one). ``extra`` scene fields (e.g. ``record``) are added.
    ``record`` is ``service.db.individuals.individual_record`` plus ``phenotype_object`` and
    ``environment`` (the one used).
    """
    record = individual_record(engine, individual_id)
    evaluations = record["evaluations"]
    if environment is None:
        if evaluations.empty:
            raise UserError(f"individual {individual_id} was never evaluated; give --environment")
        environment = str(evaluations["environment"].iloc[-1])
    if environment not in ("land", "water"):
        raise UserError(f"environment must be land or water (got {environment!r})")
    treatment: Settings = record["treatment"]
    phenotype = develop_genome(record["genome"], treatment, record["seed"])
    if phenotype.voxel_count == 0:
        raise UserError(f"individual {individual_id} has an empty body: nothing to simulate")
    scene = phenotype.to_scene(environment, treatment.stiffness_pa, treatment.cycles, **extra)
    return scene, {**record, "phenotype_object": phenotype, "environment": environment}
