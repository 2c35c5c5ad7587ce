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
phylogeny and lineage (REST and ``softevo phylogeny``), the exaptation analysis, the
dashboard and the report::

    from softevo.evolution import traits
    traits.register(traits.Trait("height", "height (voxels)", lambda p: float(p.body.any((0, 1)).sum())))

``along_lines``: the exaptation analysis follows it along each founder's line (distance,
which changes with the world, does not). ``integer`` (a count), ``required`` (every
evaluation has a value, a failed one its worst) and ``header`` (a short column title for
tables) say how storage, REST and the command line show it: the built-in columns and the
REST fields of a trait are generated from these records, never written out again.

``bounds`` (low, high), where a trait has a range of its own, make it a MAP-Elites measure
without bounds given (``evolution.archive.grid_of``): ``active_share``, ``symmetry`` and
``branching`` 0..1 (shares and an index in [0, 1]); ``shape_entropy`` 0..log2(10) bits (a
surface vertex's angle defect is (4 - n) pi/2 for the n = 3 .. 12 exposed squares around it:
at most ten bins, ``evolution.descriptors``); ``frequency`` 0..5 Hz, the range of every
bounded control mapping (``linear``: 1..5 Hz by default; the evosoro mappings read through the
logistic or clipped: 0..4 Hz; an unbounded mapping's faster robots fall in the top cell).
``voxel_count``'s range is the treatment's workspace (1 .. its volume): ``grid_of`` gives it
from there; ``distance``, the fitness, has none.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from softevo.evolution.genotype import EVOSORO_MAX_FREQUENCY, EncodingConfig
from softevo.sim.registry import Registry

FREQUENCY_BOUNDS = (0.0, max(EncodingConfig().frequency_range[1], EVOSORO_MAX_FREQUENCY))  # Hz
SHAPE_ENTROPY_BOUNDS = (0.0, math.log2(10))  # bits: at most ten curvature bins (module doc)


@dataclass(frozen=True)
class Trait:
    """One measured trait: ``name`` (snake_case), ``label`` (with its unit), and for a trait
    of the body ``compute(phenotype)``; see the module doc."""

    name: str
    label: str
    compute: Callable[[Any], float | None] | None = None
    along_lines: bool = True
    column: bool = False
    integer: bool = False
    required: bool = False
    header: str = ""
    bounds: tuple[float, float] | None = None

    @property
    def title(self) -> str:
        """The short column title of tables (``header``, else the name)."""
        return self.header or self.name


BUILT_IN = (
    Trait("distance", "distance (voxel lengths)", along_lines=False, column=True, required=True),
    Trait("active_share", "active share", column=True, required=True, header="active", bounds=(0.0, 1.0)),
    Trait("voxel_count", "voxel count", column=True, integer=True, required=True, header="voxels"),
    Trait("frequency", "frequency (Hz)", column=True, header="freq", bounds=FREQUENCY_BOUNDS),
    Trait("symmetry", "symmetry index", column=True, header="symm", bounds=(0.0, 1.0)),
    Trait("branching", "branching index", column=True, header="branch", bounds=(0.0, 1.0)),
    Trait("shape_entropy", "shape entropy (bits)", column=True, header="entropy",
          bounds=SHAPE_ENTROPY_BOUNDS),
)
_REGISTRY: Registry[Trait] = Registry("trait", BUILT_IN)
unregister, get, names, all_traits = _REGISTRY.unregister, _REGISTRY.get, _REGISTRY.names, _REGISTRY.records


def register(trait: Trait) -> Trait:
    """Add ``trait`` (ValueError for a name taken or not a lower-case identifier, or a trait
    that does not compute itself)."""
    if not trait.name.isidentifier() or not trait.name.islower():
        raise ValueError(f"trait names are lower-case identifiers (got {trait.name!r})")
    if trait.compute is None or trait.column or trait.required:
        raise ValueError("a registered trait computes itself from the phenotype, has no column and may "
                         "have no value")
    if trait.bounds is not None and not _proper(trait.bounds):
        raise ValueError(f"trait {trait.name!r}: bounds must be two finite numbers low < high")
    return _REGISTRY.register(trait)


def _proper(bounds: tuple[float, float]) -> bool:
    try:
        low, high = (float(value) for value in bounds)
    except (TypeError, ValueError):
        return False
    return math.isfinite(low) and math.isfinite(high) and low < high


def columns() -> tuple[str, ...]:
    """The traits with SQL columns of their own (the built-in ones)."""
    return tuple(trait.name for trait in _REGISTRY.records() if trait.column)


def column_traits() -> tuple[Trait, ...]:
    """The records of the traits with SQL columns of their own, in registry order."""
    return tuple(trait for trait in _REGISTRY.records() if trait.column)


def registered() -> tuple[str, ...]:
    """The traits ``register`` added (not built in), in the order added."""
    return tuple(trait.name for trait in _REGISTRY.added())


def along_lines() -> tuple[str, ...]:
    """The traits the exaptation analysis follows along each line."""
    return tuple(trait.name for trait in _REGISTRY.records() if trait.along_lines)


def headers() -> dict[str, str]:
    """{name: short column title} of every trait (``Trait.title``)."""
    return {trait.name: trait.title for trait in _REGISTRY.records()}


def labels() -> dict[str, str]:
    """{name: label} of every trait, and ``best_distance``'s."""
    return {"best_distance": "best distance (voxel lengths)",
            **{trait.name: trait.label for trait in _REGISTRY.records()}}


def computed(phenotype: Any) -> dict[str, float | None]:
    """The values of the registered traits that compute themselves from ``phenotype``; a
    trait whose computation fails, or gives a value that is not finite, is None (a trait
    never fails an evaluation, and JSON has no NaN)."""
    values: dict[str, float | None] = {}
    for trait in _REGISTRY.records():
        if trait.compute is None:
            continue
        try:
            value = trait.compute(phenotype)
            value = None if value is None else float(value)
            values[trait.name] = value if value is None or math.isfinite(value) else None
        except Exception:  # noqa: BLE001 - a trait never fails an evaluation
            values[trait.name] = None
    return values
