"""What one evaluation is (``EvaluationSpec``) and the scenes it simulates.

``EvaluationSpec`` is the one carrier of an evaluation's parameters: its world, Young's
modulus, cycles, physics model, cap on seconds and the encoding that develops the genome. A
treatment makes it (``evolution.treatments.Treatment.evaluation``), the algorithm's config
carries it (``EvolutionConfig.evaluation``), and so does every task a worker receives
(``worker.tasks.Task.evaluation``); stored settings read into one through
``EvaluationSpec.from_settings``.

``evaluation_scenes(phenotype, environment, ...)`` is the one path from a phenotype to what
the simulator runs: one scene for a pure world (``Phenotype.to_scene``), one scene per part
of a compound world (``evolution.environments``: ``land>water@0.250`` runs 75% of the cycles, and
of the cap on seconds, on land, then 25% in water, each part from rest).
``Outcome.combine`` (``evolution.outcome``) is the evaluation of those parts: their distances
added, stable if every part is. Every evaluation (the coordinator's, ``softevo.evolve``'s) goes
through the workers (``worker.tasks.scenes_of``, ``worker.evaluate``), which use these two.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from softevo.evolution import environments
from softevo.evolution.genotype import EncodingConfig, Phenotype, duration_of
from softevo.sim.models import DEFAULT as DEFAULT_MODEL
from softevo.sim.scene import DEFAULT_CYCLES

DEFAULT_YOUNGS_MODULUS = 1e6  # Pa: 1 MPa, the quick start's stiffness (the paper's S4)


@dataclass(frozen=True)
class EvaluationSpec:
    """The parameters of one evaluation: ``environment`` (a world of ``sim.worlds``, or a
    compound world ``land>water@0.250``), ``youngs_modulus`` (Pa), ``cycles`` of actuation,
    the physics ``model`` (``sim.models.names()``), ``max_seconds`` (the cap on an evaluation's
    seconds after settling; None: cycles only) and the ``encoding`` that develops genomes."""

    environment: str = environments.LAND.name
    youngs_modulus: float = DEFAULT_YOUNGS_MODULUS
    cycles: int = DEFAULT_CYCLES
    model: str = DEFAULT_MODEL
    max_seconds: float | None = None
    encoding: EncodingConfig = field(default_factory=EncodingConfig)

    def in_world(self, environment: str, youngs_modulus: float | None = None) -> EvaluationSpec:
        """The same evaluation in ``environment`` (and at ``youngs_modulus`` Pa when given)."""
        modulus = self.youngs_modulus if youngs_modulus is None else float(youngs_modulus)
        return dataclasses.replace(self, environment=environment, youngs_modulus=modulus)

    def scenes(self, phenotype: Phenotype, **extra: Any) -> list[dict[str, Any]]:
        """The scenes that evaluate ``phenotype`` (``evaluation_scenes``)."""
        return evaluation_scenes(phenotype, self.environment, self.youngs_modulus, self.cycles,
                                 model=self.model, max_seconds=self.max_seconds, **extra)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON, the flat form tasks have always had on the wire: ``environment``,
        ``youngs_modulus``, ``cycles``, ``workspace``, ``encoding``, and ``model`` and
        ``max_seconds`` only where they differ from the defaults."""
        out: dict[str, Any] = {
            "environment": self.environment,
            "youngs_modulus": float(self.youngs_modulus),
            "cycles": int(self.cycles),
            "workspace": list(self.encoding.workspace),
            "encoding": self.encoding.to_dict(),
        }
        if self.model != DEFAULT_MODEL:
            out["model"] = self.model
        if self.max_seconds is not None:
            out["max_seconds"] = float(self.max_seconds)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> EvaluationSpec:
        """The spec of ``to_dict``'s JSON (a task's); an absent ``encoding`` is the default
        one over ``workspace``. KeyError if a required key is missing."""
        encoding = data.get("encoding") or None
        config = (EncodingConfig.from_dict(encoding) if encoding
                  else EncodingConfig(workspace=tuple(int(n) for n in data["workspace"])))
        cap = data.get("max_seconds")
        return cls(
            environment=str(data["environment"]),
            youngs_modulus=float(data["youngs_modulus"]),
            cycles=int(data["cycles"]),
            model=str(data.get("model", DEFAULT_MODEL)),
            max_seconds=None if cap is None else float(cap),
            encoding=config,
        )

    @classmethod
    def from_settings(cls, settings: Mapping[str, Any], environment: str | None = None,
                      youngs_modulus: float | None = None) -> EvaluationSpec:
        """The evaluation of a treatment's stored settings (``Treatment.to_settings()``) in
        ``environment`` (default: its first world) at ``youngs_modulus`` Pa (default: its
        ``stiffness_mpa``). Settings stored before a field existed read as its default: the
        ``voxelyze-2`` model, no cap, the encoding options' defaults (``evolution.options``)."""
        first = (str(settings["environment"]).split(environments.TRANSITION)[0]
                 if environment is None else environment)
        modulus = float(settings["stiffness_mpa"]) * 1e6 if youngs_modulus is None else float(youngs_modulus)
        cap = settings.get("max_seconds")
        return cls(
            environment=first,
            youngs_modulus=modulus,
            cycles=int(settings["cycles"]),
            model=str(settings.get("model", DEFAULT_MODEL)),
            max_seconds=None if cap is None else float(cap),
            encoding=encoding_from_settings(settings),
        )


def encoding_from_settings(settings: Mapping[str, Any]) -> EncodingConfig:
    """The ``EncodingConfig`` a treatment's runs express their genomes with, from its stored
    settings: every declared option that sets the encoding (``evolution.options.encoding_of``:
    workspace, mapping, body rule, evolved stiffness and its range in MPa, per-voxel
    frequency); absent ones (older settings) give their defaults."""
    from softevo.evolution import options  # options reads the algorithms, which read this module

    return options.encoding_of(settings)


def evaluation_scenes(
    phenotype: Phenotype,
    environment: str,
    youngs_modulus: float,
    cycles: int,
    *,
    model: str = DEFAULT_MODEL,
    max_seconds: float | None = None,
    arrays: bool = False,
    **extra: Any,
) -> list[dict[str, Any]]:
    """The scenes (docs/spec.md section 1) that evaluate ``phenotype`` in ``environment``
    (a pure or compound world) at ``youngs_modulus`` (Pa) for ``cycles`` cycles, capped at
    ``max_seconds`` seconds when given, in the physics ``model``; one per part of the
    world, in the order simulated. ``extra`` scene fields (e.g. ``record``) go into each;
    ``arrays``: the phenotype's arrays, not lists (``Phenotype.to_scene``)."""
    parts = environments.parts(environment)
    scenes = []
    for world, share in parts:
        scene = phenotype.to_scene(
            world, youngs_modulus, cycles, model=model, max_seconds=max_seconds, arrays=arrays,
            **extra
        )
        if len(parts) > 1:
            scene["duration"] = duration_of(cycles, max_seconds, share)
        scenes.append(scene)
    return scenes
