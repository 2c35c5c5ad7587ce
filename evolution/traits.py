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
_REGISTRY: dict[str, Trait] = {trait.name: trait for trait in BUILT_IN}


def register(trait: Trait) -> Trait:
    """Add ``trait`` (ValueError for a name taken or not an identifier)."""
    if not trait.name.isidentifier() or not trait.name.islower():
        raise ValueError(f"trait names are lower-case identifiers (got {trait.name!r})")
    if trait.name in _REGISTRY:
        raise ValueError(f"trait {trait.name!r} is registered already")
    if trait.compute is None or trait.column:
        raise ValueError("a registered trait computes itself from the phenotype and has no column")
    _REGISTRY[trait.name] = trait
    return trait


def unregister(name: str) -> None:
    """Remove a registered trait (the built-in ones stay)."""
    if name in {trait.name for trait in BUILT_IN}:
        raise ValueError(f"{name!r} is a built-in trait")
    _REGISTRY.pop(name, None)


def all_traits() -> tuple[Trait, ...]:
    """Every trait, the built-in ones first, then in the order registered."""
    return tuple(_REGISTRY.values())


def names() -> tuple[str, ...]:
    """Every trait's name (``all_traits``)."""
    return tuple(_REGISTRY)


def columns() -> tuple[str, ...]:
    """The traits with SQL columns of their own (the built-in ones)."""
    return tuple(trait.name for trait in _REGISTRY.values() if trait.column)


def along_lines() -> tuple[str, ...]:
    """The traits the exaptation analysis follows along each line."""
    return tuple(trait.name for trait in _REGISTRY.values() if trait.along_lines)


def labels() -> dict[str, str]:
    """{name: label} of every trait, and ``best_distance``'s."""
    return {"best_distance": "best distance (voxel lengths)",
            **{trait.name: trait.label for trait in _REGISTRY.values()}}


def computed(phenotype: Any) -> dict[str, float | None]:
    """The values of the registered traits that compute themselves from ``phenotype``; a
    trait whose computation fails is None (a trait never fails an evaluation)."""
    values: dict[str, float | None] = {}
    for trait in _REGISTRY.values():
        if trait.compute is None:
            continue
        try:
            value = trait.compute(phenotype)
            values[trait.name] = None if value is None else float(value)
        except Exception:  # noqa: BLE001 - a trait never fails an evaluation
            values[trait.name] = None
    return values
