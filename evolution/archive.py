"""A MAP-Elites archive as a pure function of the evaluations: the grid over registered traits
and the elites a run's evaluations leave in it.

A ``Grid`` divides the space of some registered traits (the ``measures``) into ``cells``
per measure between ``bounds``. Where an evaluation's measures fall is pyribs' rule
(``ribs.archives.GridArchive.index_of``): each measure's cell index is
``int((cells * (value - low) + EPSILON) / (high - low))``, truncated towards zero and then
clipped into ``0 .. cells - 1`` (a value outside the bounds lands in the edge cell); the
cell's flat index is the row-major one of ``numpy.ravel_multi_index``. An evaluation with a
measure missing (None) or not finite falls in no cell.

``elites(grid, candidates)`` replays the MAP-Elites insertion rule over candidates in the
order they were evaluated: a cell keeps its farthest candidate, and a later candidate takes
the cell only when strictly farther (ties keep the earlier, as pyribs does). The archive after
generation g is therefore ``elites`` of the evaluations of generations 0 .. g, which is how
storage, the command line, REST and the report compute it from the stored evaluations: the
archive needs no table of its own, and a resumed run's archive is its evaluations'.

The order is the one the algorithm inserts in (``evolution.operators.archive_survival``):
by generation, then within a generation by the individual's run-local id (``local_id`` of
the stored individuals and evaluations), ascending; a generation's evaluations are its
individuals in the order they were bred, which is their ids' order. Failed evaluations are
candidates like the others (their distance is 0); one without a value for some measure (an
empty body has no descriptors) falls in no cell.

A world left behind leaves its archive behind: at a transition's switch (and at each
generation of a gradual switch-over: ``evolution.treatments``) the elites are evaluated
again in the new world and the archive starts afresh from those evaluations. The archive
after generation g is thus ``elites`` of the evaluations of generations 0 .. g *in generation
g's world* (``current``): for a run in one world, all of them.

``grid_of(treatment)`` is the grid of a treatment's options ``measures``, ``cells`` and
``measure_bounds`` (``evolution.options``). ``summary(grid, elites)`` is the JSON of
``softevo archive`` and ``GET /runs/{id}/archive``.
The QD score is the sum over elites of their distance less ``QD_OFFSET`` (pyribs'
``qd_score`` with ``qd_score_offset``), coverage the share of cells filled.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from softevo.evolution import traits

EPSILON = 1e-6  # pyribs' GridArchive default
QD_OFFSET = 0.0  # distances are displacements >= 0: the QD score is the sum of the elites'
MAX_CELLS = 10_000  # the most cells a treatment's grid may have (its elites are the population)


@dataclass(frozen=True)
class Grid:
    """The cells of a MAP-Elites archive: ``measures`` (trait names), their ``bounds``
    ((low, high) each, low < high) and ``cells`` (per measure, >= 1)."""

    measures: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    cells: tuple[int, ...]

    def __post_init__(self) -> None:
        if not (len(self.measures) == len(self.bounds) == len(self.cells)) or not self.measures:
            raise ValueError("a grid needs one bound pair and one cell count per measure")
        for name, (low, high), count in zip(self.measures, self.bounds, self.cells, strict=True):
            if not (math.isfinite(low) and math.isfinite(high) and low < high):
                raise ValueError(f"measure {name!r}: bounds must be finite with low < high")
            if count < 1:
                raise ValueError(f"measure {name!r}: at least one cell")

    @property
    def size(self) -> int:
        """The number of cells."""
        return math.prod(self.cells)

    def cell_of(self, values: Mapping[str, Any]) -> tuple[int, ...] | None:
        """The grid indices of the cell ``values`` (by measure name) fall in, or None when a
        measure is missing or not finite."""
        cell = []
        for name, (low, high), count in zip(self.measures, self.bounds, self.cells, strict=True):
            value = values.get(name)
            if value is None or not math.isfinite(float(value)):
                return None
            index = int((count * (float(value) - low) + EPSILON) / (high - low))
            cell.append(min(max(index, 0), count - 1))
        return tuple(cell)

    def index(self, cell: Sequence[int]) -> int:
        """The flat (row-major) index of grid indices ``cell``."""
        flat = 0
        for position, count in zip(cell, self.cells, strict=True):
            flat = flat * count + int(position)
        return flat

    def edges(self) -> list[list[float]]:
        """Each measure's cell boundaries (cells + 1 values, low to high)."""
        return [[low + (high - low) * k / count for k in range(count + 1)]
                for (low, high), count in zip(self.bounds, self.cells, strict=True)]

    def to_json(self) -> dict[str, Any]:
        return {"measures": list(self.measures), "bounds": [list(b) for b in self.bounds],
                "cells": list(self.cells)}


@dataclass(frozen=True)
class Candidate:
    """One evaluation offered to the archive: the individual (its id where stored), its
    distance, its trait values (at least the grid's measures) and the generation."""

    individual: int
    distance: float
    measures: Mapping[str, Any]
    generation: int = 0


@dataclass(frozen=True)
class Elite:
    """A cell's elite: the candidate that holds it, its cell (grid indices) and the
    generation it entered."""

    individual: int
    cell: tuple[int, ...]
    distance: float
    measures: dict[str, float] = field(default_factory=dict)
    generation: int = 0

    def to_json(self, grid: Grid) -> dict[str, Any]:
        return {"individual": self.individual, "cell": list(self.cell), "index": grid.index(self.cell),
                "distance": self.distance, "measures": self.measures, "generation": self.generation}


def elites(grid: Grid, candidates: Iterable[Candidate],
           start: Mapping[tuple[int, ...], Elite] | None = None) -> dict[tuple[int, ...], Elite]:
    """The archive after inserting ``candidates`` in order into ``start`` (empty by default)
    by the MAP-Elites rule: {cell: elite}. A candidate whose distance is missing or not
    finite, or whose measures fall in no cell, is not inserted."""
    archive = dict(start or {})
    for candidate in candidates:
        distance = candidate.distance
        if distance is None or not math.isfinite(float(distance)):
            continue
        cell = grid.cell_of(candidate.measures)
        if cell is None:
            continue
        held = archive.get(cell)
        if held is None or float(distance) > held.distance:
            archive[cell] = Elite(candidate.individual, cell, float(distance),
                                  {name: float(candidate.measures[name]) for name in grid.measures},
                                  candidate.generation)
    return archive


def qd_score(archive: Mapping[tuple[int, ...], Elite]) -> float:
    """The sum over elites of their distance less ``QD_OFFSET``."""
    return float(sum(elite.distance - QD_OFFSET for elite in archive.values()))


def coverage(grid: Grid, archive: Mapping[tuple[int, ...], Elite]) -> float:
    """The share of the grid's cells that hold an elite."""
    return len(archive) / grid.size


def summary(grid: Grid, archive: Mapping[tuple[int, ...], Elite]) -> dict[str, Any]:
    """The archive as JSON: the grid, ``coverage``, ``qd_score``, ``filled`` and the
    ``elites`` in flat-index order."""
    ordered = sorted(archive.values(), key=lambda elite: grid.index(elite.cell))
    return {**grid.to_json(), "coverage": coverage(grid, archive), "qd_score": qd_score(archive),
            "filled": len(archive), "elites": [elite.to_json(grid) for elite in ordered]}


def current(candidates: Iterable[Candidate], world_of: Mapping[int, str], generation: int
            ) -> list[Candidate]:
    """The candidates of generations 0 .. ``generation`` evaluated in ``generation``'s world,
    in insertion order (generation, then individual): those the archive after
    ``generation`` is made of. ``world_of`` maps each candidate's generation to its world
    (the stored evaluations' ``environment``)."""
    world = world_of[generation]
    kept = [c for c in candidates if c.generation <= generation and world_of[c.generation] == world]
    return sorted(kept, key=lambda c: (c.generation, c.individual))


def grid_of(treatment: Any) -> Grid:
    """The grid of a treatment's ``measures`` (registered traits), ``cells`` (one count per
    measure) and ``measure_bounds`` (low, high per measure, flattened; none: each trait's
    ``bounds``, ``voxel_count``'s 1 .. the workspace's volume). ValueError, in one line, for
    a measure that is not a registered trait or has no bounds, counts that do not match,
    bounds with low >= high or more than ``MAX_CELLS`` cells."""
    measures = tuple(treatment.measures)
    cells = tuple(int(count) for count in treatment.cells)
    given = tuple(float(value) for value in (treatment.measure_bounds or ()))
    if not measures:
        raise ValueError("measures: name at least one trait")
    if len(set(measures)) != len(measures):
        raise ValueError(f"measures: each trait once (got {', '.join(measures)})")
    unknown = [name for name in measures if name not in traits.names()]
    if unknown:
        raise ValueError(f"measures: {', '.join(unknown)} is no registered trait; choose among "
                         f"{', '.join(traits.names())}")
    if len(cells) != len(measures):
        raise ValueError(f"cells: one count per measure ({len(measures)}: {', '.join(measures)}; "
                         f"got {len(cells)})")
    if given and len(given) != 2 * len(measures):
        raise ValueError(f"measure_bounds: low,high for each of the {len(measures)} measures "
                         f"({2 * len(measures)} numbers; got {len(given)})")
    bounds = []
    for k, name in enumerate(measures):
        pair = given[2 * k: 2 * k + 2] if given else _bounds_of(name, treatment)
        if pair is None:
            raise ValueError(f"measure {name} has no bounds of its own: give measure_bounds")
        if not (math.isfinite(pair[0]) and math.isfinite(pair[1]) and pair[0] < pair[1]):
            raise ValueError(f"measure_bounds of {name} must be finite with low < high "
                             f"(got {pair[0]:g},{pair[1]:g})")
        bounds.append((float(pair[0]), float(pair[1])))
    if math.prod(cells) > MAX_CELLS:
        raise ValueError(f"cells: at most {MAX_CELLS:,} in all (got {'x'.join(map(str, cells))} = "
                         f"{math.prod(cells):,})")
    return Grid(measures, tuple(bounds), cells)


def _bounds_of(name: str, treatment: Any) -> tuple[float, float] | None:
    """A measure's own bounds: its trait's, ``voxel_count``'s from the treatment's workspace."""
    if name == "voxel_count":
        return 1.0, float(max(2, math.prod(treatment.workspace)))
    return traits.get(name).bounds
