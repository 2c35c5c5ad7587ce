"""The operators an algorithm is composed of (``evolution.algorithm.Algorithm``), after
pymoo's survival and mating operators.

- A ``Survival`` cuts survivors and offspring back to the population size:
  ``survival(F, size, ages, valid, rng) -> kept``, where ``F`` (n, m) is the objectives
  matrix in minimisation form (``selection.objective_matrix``) with its rows in id order
  (the older individual first), ``ages`` (n,) int the rows' ages, ``valid`` (n,) bool False
  for a failed evaluation, ``rng`` the run's ``numpy.random.Generator`` and ``kept`` the
  indices of the rows that survive (at most ``size``). Built in: ``nsga2_survival``
  (``selection.select_survivors``) and ``evosoro_survival`` (``selection.evosoro_survivors``).
- A ``Variation`` makes part of a generation's new individuals from the survivors:
  ``variation(breeder, parents) -> offspring``, through the breeder's ``mutant(parent)`` (a
  child of the CPPN mutation, ``genotype.mutate_developed``) and ``newcomer()`` (a random
  viable individual of age 0, ``genotype.random_viable``), the two ways the run's random
  generator makes individuals. Built in: ``mutate_each`` (one child per survivor) and
  ``random_newcomers(n)``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from softevo.evolution.individual import Individual
from softevo.evolution.selection import evosoro_survivors, select_survivors

Survival = Callable[[np.ndarray, int, np.ndarray, np.ndarray, np.random.Generator], np.ndarray]


class Breeder(Protocol):
    """What a variation makes individuals with (``evolution.algorithm.Evolution``)."""

    def mutant(self, parent: Individual) -> Individual: ...

    def newcomer(self) -> Individual: ...


Variation = Callable[[Breeder, Sequence[Individual]], list[Individual]]


def nsga2_survival(F: np.ndarray, size: int, ages: np.ndarray, valid: np.ndarray,
                   rng: np.random.Generator) -> np.ndarray:
    """AFPO's survival (``selection.select_survivors``): successive non-dominated fronts,
    the front that does not fit cut by crowding distance, then by lower id. Draws nothing."""
    return select_survivors(F, size, valid)


def evosoro_survival(F: np.ndarray, size: int, ages: np.ndarray, valid: np.ndarray,
                     rng: np.random.Generator) -> np.ndarray:
    """The paper's survival (``selection.evosoro_survivors``): levels by dominance count,
    the newer of identical twins preferred, a log-biased random pick within the level that
    does not fit."""
    return evosoro_survivors(F, size, ages, rng, valid)


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

