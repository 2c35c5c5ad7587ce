"""The operators an algorithm is composed of (``evolution.algorithm.Algorithm``), after
pymoo's survival and mating operators.

- A ``Survival`` cuts survivors and offspring back to the population size:
  ``survival(candidates, size, rng) -> kept``, where ``candidates`` (``Candidates``) holds
  the objectives matrix ``F`` in minimisation form (``selection.objective_matrix``) with its
  rows in id order (the older individual first) and its columns the run's objectives then
  the algorithm's (``objectives``), the rows' ``ages`` and ``valid`` (False for a failed
  evaluation); ``rng`` is the run's ``numpy.random.Generator`` and ``kept`` the indices of
  the rows that survive (at most ``size``). Built in: ``nsga2_survival``
  (``selection.select_survivors``), ``evosoro_survival`` (``selection.evosoro_survivors``)
  and ``truncation(name)`` (the best on one objective).
- A ``Variation`` makes part of a generation's new individuals from the survivors:
  ``variation(breeder, parents) -> offspring``, through the breeder's ``mutant(parent)`` (a
  child of the CPPN mutation, ``genotype.mutate_developed``) and ``newcomer()`` (a random
  viable individual of age 0, ``genotype.random_viable``), the two ways the run's random
  generator makes individuals. Built in: ``mutate_each`` (one child per survivor) and
  ``random_newcomers(n)``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple, Protocol

import numpy as np

from softevo.evolution.individual import Individual
from softevo.evolution.selection import Objective, evosoro_survivors, select_survivors


class Candidates(NamedTuple):
    """Survivors and offspring as a survival sees them, rows in id order.

    F: (n, m) float, minimisation form; objectives: (m,) the ``Objective`` of each column;
    ages: (n,) int; valid: (n,) bool, False for a failed evaluation.
    """

    F: np.ndarray
    objectives: tuple[Objective, ...]
    ages: np.ndarray
    valid: np.ndarray

    def column(self, name: str) -> np.ndarray:
        """(n,) float: the objective ``name``'s column of ``F`` (minimisation form)."""
        names = [objective.name for objective in self.objectives]
        return self.F[:, names.index(name)]


Survival = Callable[[Candidates, int, np.random.Generator], np.ndarray]


class Breeder(Protocol):
    """What a variation makes individuals with (``evolution.algorithm.Evolution``)."""

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

