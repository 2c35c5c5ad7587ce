"""The operators an algorithm is composed of (``evolution.algorithm.Algorithm``), after
pymoo's survival and mating operators.

- A ``Survival`` cuts survivors and offspring back to the population size:
  ``survival(candidates, size, rng) -> kept``, where ``candidates`` (``Candidates``) holds
  the objectives matrix ``F`` in minimisation form (``selection.objective_matrix``) with its
  rows in id order (the older individual first) and its columns the run's objectives then
  the algorithm's (``objectives``), the rows' ``ages`` and ``valid`` (False for a failed
  evaluation); ``rng`` is the run's ``numpy.random.Generator`` and ``kept`` the indices of
  the rows that survive (at most ``size``, but for an archive's: its elites, however many).
  For an algorithm with ``archive`` set, ``candidates`` also holds the run's ``grid``
  (``evolution.archive.Grid``) and each row's ``measures`` (NaN where missing). Built in:
  ``nsga2_survival`` (``selection.select_survivors``), ``evosoro_survival``
  (``selection.evosoro_survivors``), ``truncation(name)`` (the best on one objective) and
  ``archive_survival`` (MAP-Elites: the elites of a pyribs ``GridArchive``).
- A ``Variation`` makes part of a generation's new individuals from the survivors:
  ``variation(breeder, parents) -> offspring``, through the breeder's ``mutant(parent)`` (a
  child of the CPPN mutation, ``genotype.mutate_developed``) and ``newcomer()`` (a random
  viable individual of age 0, ``genotype.random_viable``), the two ways the run's random
  generator makes individuals; ``breeder.rng`` is that generator and ``breeder.batch_size``
  the population size. Built in: ``mutate_each`` (one child per survivor),
  ``random_newcomers(n)`` and ``uniform_mutants`` (MAP-Elites: a batch of children of parents
  drawn uniformly).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple, Protocol

import numpy as np

from softevo.evolution.archive import EPSILON, QD_OFFSET, Grid
from softevo.evolution.individual import Individual
from softevo.evolution.selection import Objective, evosoro_survivors, select_survivors


class Candidates(NamedTuple):
    """Survivors and offspring as a survival sees them, rows in id order.

    F: (n, m) float, minimisation form; objectives: (m,) the ``Objective`` of each column;
    ages: (n,) int; valid: (n,) bool, False for a failed evaluation; for an algorithm with an
    archive, ``grid`` (the run's) and ``measures``: (n, k) float, each row's value of the
    grid's k measures (NaN where it has none).
    """

    F: np.ndarray
    objectives: tuple[Objective, ...]
    ages: np.ndarray
    valid: np.ndarray
    measures: np.ndarray | None = None
    grid: Grid | None = None

    def column(self, name: str) -> np.ndarray:
        """(n,) float: the objective ``name``'s column of ``F`` (minimisation form)."""
        names = [objective.name for objective in self.objectives]
        return self.F[:, names.index(name)]


Survival = Callable[[Candidates, int, np.random.Generator], np.ndarray]


class Breeder(Protocol):
    """What a variation makes individuals with (``evolution.algorithm.Evolution``)."""

    rng: np.random.Generator

    @property
    def batch_size(self) -> int: ...

    def mutant(self, parent: Individual) -> Individual: ...

    def newcomer(self) -> Individual: ...


Variation = Callable[[Breeder, Sequence[Individual]], list[Individual]]


def nsga2_survival(candidates: Candidates, size: int, rng: np.random.Generator) -> np.ndarray:
    """AFPO's survival (``selection.select_survivors``): successive non-dominated fronts,
    the front that does not fit cut by crowding distance, then by lower id. Draws nothing."""
    return select_survivors(candidates.F, size, candidates.valid)


def evosoro_survival(candidates: Candidates, size: int, rng: np.random.Generator) -> np.ndarray:
    """The paper's survival (``selection.evosoro_survivors``): levels by dominance count,
    the newer of identical twins preferred, a log-biased random pick within the level that
    does not fit."""
    return evosoro_survivors(candidates.F, size, candidates.ages, rng, candidates.valid)


def truncation(name: str) -> Survival:
    """A survival keeping the ``size`` best on the objective ``name`` alone (failed
    evaluations last, ties to the lower id). Draws nothing."""

    def survive(candidates: Candidates, size: int, rng: np.random.Generator) -> np.ndarray:
        order = np.lexsort((candidates.column(name), ~candidates.valid))  # valid first, then best
        return np.sort(order[:size])

    survive.__name__ = f"truncation({name})"
    return survive


def archive_survival(candidates: Candidates, size: int, rng: np.random.Generator) -> np.ndarray:
    """MAP-Elites' survival: the rows, in order, go into a pyribs ``GridArchive`` over the
    grid (``add_single``: a row takes an empty cell, or a held one when strictly farther:
    ``evolution.archive.elites``'s rule); the rows kept are its elites, however many (the
    population size is the batch's). A row with a distance or measure that is not finite
    goes in no cell. Measures are clipped to one grid's width beyond their bounds first: the
    cell is the same (pyribs clips the index), and a far value cannot overflow pyribs'
    32-bit index. Draws nothing."""
    from ribs.archives import GridArchive  # pyribs loads numba and scikit-learn: when first used

    grid, measures = candidates.grid, candidates.measures
    if grid is None or measures is None:
        raise ValueError("archive_survival needs the run's grid and each candidate's measures")
    archive = GridArchive(solution_dim=1, dims=grid.cells, ranges=grid.bounds, epsilon=EPSILON,
                          qd_score_offset=QD_OFFSET)
    distances = -candidates.column("distance")  # minimisation form back to the distance
    low, high = np.array(grid.bounds, dtype=float).T
    low, high = low - (high - low), high + (high - low)
    for row, (distance, values) in enumerate(zip(distances, measures, strict=True)):
        if np.isfinite(distance) and np.all(np.isfinite(values)):
            archive.add_single([row], distance, np.clip(values, low, high))
    return np.sort(archive.data("solution")[:, 0].astype(int))


def mutate_each(breeder: Breeder, parents: Sequence[Individual]) -> list[Individual]:
    """One mutated child per parent, in the parents' order (the child inherits its parent's
    age and differs from it in phenotype)."""
    return [breeder.mutant(parent) for parent in parents]


def random_newcomers(count: int) -> Variation:
    """A variation adding ``count`` random newcomers of age 0 each generation (AFPO's one)."""

    def newcomers(breeder: Breeder, parents: Sequence[Individual]) -> list[Individual]:
        return [breeder.newcomer() for _ in range(count)]

    newcomers.__name__ = f"random_newcomers({count})"
    return newcomers


def uniform_mutants(breeder: Breeder, parents: Sequence[Individual]) -> list[Individual]:
    """MAP-Elites' variation: ``breeder.batch_size`` children, each of a parent drawn
    uniformly (with replacement, by the run's generator) from ``parents`` (the archive's
    elites, in id order); a batch of random newcomers while the archive is empty."""
    if not parents:
        return [breeder.newcomer() for _ in range(breeder.batch_size)]
    picks = breeder.rng.integers(len(parents), size=breeder.batch_size)
    return [breeder.mutant(parents[int(pick)]) for pick in picks]
