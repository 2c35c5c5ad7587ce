"""The traits of an evaluated robot: one registry that storage, the REST API, the dashboard,
the exaptation analysis and the report all read.

A ``Trait`` is a name (a column of the analyses and a key of an evaluation's
``descriptors``), a label for people (axis titles, tables) and, for a trait of the body,
``compute(phenotype) -> float | None``. The built-in seven (``distance``, ``active_share``,
``voxel_count``, ``frequency``, ``symmetry``, ``branching``, ``shape_entropy``) are measured
where the genome is evaluated (``worker.tasks``, ``evolution.descriptors``) and have SQL
columns of their own (``column=True``). A trait registered later needs nothing else: its
value is computed from the phenotype when the generation is told
(``evolution.runner.tell_generation``, as the coordinator and ``softevo.evolve`` both tell),
kept in the evaluation's ``descriptors`` (the JSON column ``evaluations.descriptors``), and
read from there into the analyses' columns, the REST ``traits`` of each evaluation, the
dashboard and the report::

    from softevo.evolution import traits
    traits.register(traits.Trait("height", "height (voxels)", lambda p: float(p.body.any((0, 1)).sum())))

``along_lines``: the exaptation analysis follows it along each founder's line (distance,
which changes with the world, does not).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from softevo.sim.registry import Registry


@dataclass(frozen=True)
class Trait:
    """One measured trait: ``name`` (snake_case), ``label`` (with its unit), and for a trait
    of the body ``compute(phenotype)``; see the module doc."""

    name: str
    label: str
    compute: Callable[[Any], float | None] | None = None
    along_lines: bool = True
    column: bool = False


BUILT_IN = (
    Trait("distance", "distance (voxel lengths)", along_lines=False, column=True),
    Trait("active_share", "active share", column=True),
    Trait("voxel_count", "voxel count", column=True),
    Trait("frequency", "frequency (Hz)", column=True),
    Trait("symmetry", "symmetry index", column=True),
    Trait("branching", "branching index", column=True),
    Trait("shape_entropy", "shape entropy (bits)", column=True),
)
_REGISTRY: Registry[Trait] = Registry("trait", BUILT_IN)
unregister, get, names, all_traits = _REGISTRY.unregister, _REGISTRY.get, _REGISTRY.names, _REGISTRY.records


def register(trait: Trait) -> Trait:
    """Add ``trait`` (ValueError for a name taken or not a lower-case identifier, or a trait
    that does not compute itself)."""
    if not trait.name.isidentifier() or not trait.name.islower():
        raise ValueError(f"trait names are lower-case identifiers (got {trait.name!r})")
    if trait.compute is None or trait.column:
        raise ValueError("a registered trait computes itself from the phenotype and has no column")
    return _REGISTRY.register(trait)


def columns() -> tuple[str, ...]:
    """The traits with SQL columns of their own (the built-in ones)."""
    return tuple(trait.name for trait in _REGISTRY.records() if trait.column)


def along_lines() -> tuple[str, ...]:
    """The traits the exaptation analysis follows along each line."""
    return tuple(trait.name for trait in _REGISTRY.records() if trait.along_lines)


def labels() -> dict[str, str]:
    """{name: label} of every trait, and ``best_distance``'s."""
    return {"best_distance": "best distance (voxel lengths)",
            **{trait.name: trait.label for trait in _REGISTRY.records()}}


def computed(phenotype: Any) -> dict[str, float | None]:
    """The values of the registered traits that compute themselves from ``phenotype``; a
    trait whose computation fails is None (a trait never fails an evaluation)."""
    values: dict[str, float | None] = {}
    for trait in _REGISTRY.records():
        if trait.compute is None:
            continue
        try:
            value = trait.compute(phenotype)
            values[trait.name] = None if value is None else float(value)
        except Exception:  # noqa: BLE001 - a trait never fails an evaluation
            values[trait.name] = None
    return values
