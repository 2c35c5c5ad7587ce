"""The scenes of one evaluation, and the outcome they add up to.

``evaluation_scenes(phenotype, environment, ...)`` is the one path from a phenotype to what
the simulator runs: one scene for a pure world (``Phenotype.to_scene``), one scene per part
of a compound world (``evolution.worlds``: ``land>water@0.250`` runs 75% of the cycles, and
of the cap on seconds, on land, then 25% in water, each part from rest).
``compound_outcome(outcomes)`` is the evaluation of those parts: their distances added,
stable if every part is. The local run loop (``evolution.runner``) and the workers
(``worker.tasks.scenes_of``, ``worker.evaluate``) both evaluate through these two.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from softevo.evolution import worlds
from softevo.evolution.genotype import Phenotype, duration_of
from softevo.sim import models


def evaluation_scenes(
    phenotype: Phenotype,
    environment: str,
    youngs_modulus: float,
    cycles: int,
    *,
    model: str = models.DEFAULT,
    max_seconds: float | None = None,
    **extra: Any,
) -> list[dict[str, Any]]:
    """The scenes (docs/spec.md section 1) that evaluate ``phenotype`` in ``environment``
    (a pure or compound world) at ``youngs_modulus`` (Pa) for ``cycles`` cycles, capped at
    ``max_seconds`` seconds when given, in the physics ``model``; one per part of the
    world, in the order simulated. ``extra`` scene fields (e.g. ``record``) go into each."""
    parts = worlds.parts(environment)
    scenes = []
    for world, share in parts:
        scene = phenotype.to_scene(
            world, youngs_modulus, cycles, model=model, max_seconds=max_seconds, **extra
        )
        if len(parts) > 1:
            scene["duration"] = duration_of(cycles, max_seconds, share)
        scenes.append(scene)
    return scenes


@dataclass(frozen=True)
class CompoundOutcome:
    """The evaluation of a compound world's parts, read as a ``sim.Result`` is read."""

    distance: float
    stable: bool
    reason: str | None


def compound_outcome(outcomes: list[Any]) -> Any:
    """One outcome from the parts' outcomes (each a ``sim.Result``, an ``Evaluation``, a
    mapping with ``distance`` / ``stable`` / ``reason`` or ``error``, or an exception): the
    first exception if any part raised; else distance = the sum of the parts' distances
    (each the distance its part travelled in its own world and share of the time), stable if
    every part is (else the first unstable part's reason). One part is returned as it is."""
    if len(outcomes) == 1:
        return outcomes[0]
    for outcome in outcomes:
        if isinstance(outcome, BaseException):
            return outcome
    parts = [_distance_stable_reason(outcome) for outcome in outcomes]
    unstable = [reason for _, stable, reason in parts if not stable]
    return CompoundOutcome(
        distance=float(sum(distance for distance, _, _ in parts)),
        stable=not unstable,
        reason=unstable[0] if unstable else None,
    )


def _distance_stable_reason(outcome: Any) -> tuple[float, bool, str | None]:
    get = outcome.get if isinstance(outcome, Mapping) else lambda name: getattr(outcome, name, None)
    return float(get("distance")), bool(get("stable")), get("reason") or get("error")
