"""Individuals as plain data with JSON round trips. What an evaluation returns is an
``evolution.outcome.Outcome``."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from softevo.evolution.genotype import EncodingConfig, Genotype, Phenotype, develop


@dataclass
class Individual:
    """One robot in a run. Evaluation fields stay None until the individual is told a result.

    objectives: {name: value} of the run's configured objectives (``selection.objective_values``;
    the paper's: distance, active_share, voxel_count), plus "age" at selection time.
    descriptors: see ``evolution.descriptors.describe``.
    evaluated_generation: the generation whose ``tell`` gave the current evaluation.
    """

    id: int
    parent_id: int | None
    generation_born: int
    age: int
    genome: Genotype
    objectives: dict[str, float] | None = None
    descriptors: dict[str, float] | None = None
    environment: str | None = None
    stable: bool | None = None
    error: str | None = None
    evaluated_generation: int | None = None
    mutations: list[str] = field(default_factory=list)
    # the last phenotype developed, with the genome and encoding it came from (``phenotype``)
    _developed: tuple[Any, EncodingConfig, Phenotype] | None = field(
        default=None, init=False, repr=False, compare=False)

    @property
    def evaluated(self) -> bool:
        return self.objectives is not None

    @property
    def failed(self) -> bool:
        """True when evaluated and the evaluation failed or was unstable."""
        return self.evaluated and (not self.stable or self.error is not None)

    def phenotype(self, encoding: EncodingConfig) -> Phenotype:
        """The genome developed in ``encoding``; developed once while genome and encoding
        stay the same (selection, twin lookup and storage each ask for it)."""
        cached = self._developed
        if cached is not None and cached[0] is self.genome and cached[1] == encoding:
            return cached[2]
        return self.developed(encoding, develop(self.genome, encoding))

    def developed(self, encoding: EncodingConfig, phenotype: Phenotype) -> Phenotype:
        """Keep ``phenotype`` as the genome's in ``encoding`` (developed already, e.g. while
        breeding judged it) for ``phenotype`` to return; returns it."""
        self._developed = (self.genome, encoding, phenotype)
        return phenotype

    def trait_values(self, encoding: EncodingConfig, names: Sequence[str] | None = None) -> dict[str, Any]:
        """The evaluated individual's traits (``evolution.traits``) as storage records them:
        a built-in one (a column of its own) from its objectives, else its body's active share
        and voxel count, else its descriptors; a registered one computed from its phenotype
        (``traits.computed``, as ``runner.tell_generation`` adds them to the descriptors;
        only when ``names``, if given, asks for one), else its descriptors. A trait without
        a value is None or absent."""
        from softevo.evolution import traits

        phenotype = self.phenotype(encoding)
        values: dict[str, Any] = {**(self.descriptors or {})}
        wanted = traits.registered() if names is None else set(traits.registered()) & set(names)
        if wanted:
            values.update(traits.computed(phenotype))
        values.update({"active_share": phenotype.active_share, "voxel_count": float(phenotype.voxel_count),
                       **(self.objectives or {})})
        return values

    def clear_evaluation(self) -> None:
        self.objectives = self.descriptors = self.environment = None
        self.stable = self.error = self.evaluated_generation = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "parent_id": self.parent_id,
            "generation_born": self.generation_born,
            "age": self.age,
            "genome": self.genome.to_dict(),
            "objectives": self.objectives,
            "descriptors": self.descriptors,
            "environment": self.environment,
            "stable": self.stable,
            "error": self.error,
            "evaluated_generation": self.evaluated_generation,
            "mutations": list(self.mutations),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Individual:
        data = dict(data)
        data["genome"] = Genotype.from_dict(data["genome"])
        return cls(**data)
