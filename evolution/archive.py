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

``summary(grid, elites)`` is the JSON of ``softevo archive`` and ``GET /runs/{id}/archive``.
The QD score is the sum over elites of their distance less ``QD_OFFSET`` (pyribs'
``qd_score`` with ``qd_score_offset``), coverage the share of cells filled.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

EPSILON = 1e-6  # pyribs' GridArchive default
QD_OFFSET = 0.0  # distances are displacements >= 0: the QD score is the sum of the elites'


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
