"""Pareto selection as pure functions of an objectives matrix.

``F`` is an (n_individuals, n_objectives) float array in *minimisation* form: objectives to
maximise are negated by :func:`objective_matrix`. Row i dominates row j when it is no worse
on every objective and strictly better on at least one.

Two survivor selections:
- :func:`select_survivors` (AFPO): NSGA-II style, successive non-dominated fronts, the front
  that does not fit cut by crowding distance, then by lower index;
- :func:`evosoro_survivors` (``pareto``, the paper's): evosoro's ``pareto_selection``
  (tools/selection.py:5-73 of skriegman/evosoro), levels by *dominance count* and a
  log-biased random pick in the level that does not fit; see its docstring.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from softevo.sim.registry import Registry


def _distance(outcome: Any, phenotype: Any) -> float:
    return outcome.distance


def _active_share(outcome: Any, phenotype: Any) -> float:
    return phenotype.active_share


def _voxel_count(outcome: Any, phenotype: Any) -> float:
    return float(phenotype.voxel_count)


@dataclass(frozen=True)
class Objective:
    """An objective declared as data: ``name`` (the key in an individual's objectives),
    ``direction`` "max" or "min", and ``value(outcome, phenotype) -> float``, how its value
    is computed from an ``outcome.Outcome`` and the individual's ``genotype.Phenotype``
    (None: the value is given, as ``age`` is at selection time). Two objectives are equal
    when name and direction are."""

    name: str
    direction: str
    value: Callable[[Any, Any], float] | None = field(default=None, compare=False, repr=False)

    def sign(self) -> float:
        """+1 for "min", -1 for "max": multiplying by it gives minimisation form."""
        if self.direction not in ("min", "max"):
            raise ValueError(f"objective {self.name}: direction must be 'min' or 'max'")
        return 1.0 if self.direction == "min" else -1.0


PAPER_OBJECTIVES: tuple[Objective, ...] = (
    Objective("distance", "max", _distance),
    Objective("active_share", "min", _active_share),
    Objective("voxel_count", "min", _voxel_count),
)
AGE_OBJECTIVE = Objective("age", "min")

OBJECTIVES: Registry[Objective] = Registry("objective", PAPER_OBJECTIVES)
"""The objectives a run may be configured with, by name: the paper's and any registered."""


def register_objective(objective: Objective) -> Objective:
    """Make ``objective`` available by name to run configurations (``objectives_named``,
    ``EvolutionConfig.from_dict``, a treatment's ``objectives``); ValueError for a name that
    is not an identifier or is already taken, the reserved ``age``, a bad direction or no
    ``value``."""
    objective.sign()
    if not objective.name.isidentifier() or len(objective.name) > 64:
        raise ValueError(f"objective name {objective.name!r}: an identifier of at most 64 characters")
    if objective.value is None:
        raise ValueError(f"objective {objective.name}: needs a value function")
    if objective.name == AGE_OBJECTIVE.name:
        raise ValueError(f"objective {objective.name!r} is already registered")
    return OBJECTIVES.register(objective)


def unregister_objective(name: str) -> None:
    """Undo ``register_objective`` (the paper's objectives stay)."""
    if name in (o.name for o in PAPER_OBJECTIVES):
        raise ValueError(f"objective {name!r} is one of the paper's")
    OBJECTIVES.unregister(name)


def objective_named(name: str, direction: str | None = None) -> Objective:
    """The registered objective ``name``; ValueError for an unknown name or a ``direction``
    other than the registered one."""
    if name not in OBJECTIVES:
        raise ValueError(f"unknown objective {name!r}; registered: {', '.join(OBJECTIVES.names())}")
    objective = OBJECTIVES.get(name)
    if direction is not None and direction != objective.direction:
        raise ValueError(f"objective {name!r} is {objective.direction}imised (got {direction!r})")
    return objective


def objectives_named(names: Sequence[str]) -> tuple[Objective, ...]:
    """The registered objectives of ``names``, in order; the paper's when ``names`` is empty."""
    return tuple(objective_named(n) for n in names) if names else PAPER_OBJECTIVES


def objective_values(objectives: Sequence[Objective], outcome: Any, phenotype: Any) -> dict[str, float]:
    """{name: value} of each objective for one outcome of one phenotype, in order: the
    one place an individual's objectives are computed."""
    values = {}
    for objective in objectives:
        if objective.value is None:
            raise ValueError(f"objective {objective.name}: has no value function")
        values[objective.name] = objective.value(outcome, phenotype)
    return values


def objective_matrix(
    rows: Sequence[Mapping[str, float]], objectives: Sequence[Objective]
) -> np.ndarray:
    """F, shape (len(rows), len(objectives)), in minimisation form."""
    signs = np.array([o.sign() for o in objectives])
    values = np.array([[float(r[o.name]) for o in objectives] for r in rows], dtype=float)
    return values.reshape(len(rows), len(objectives)) * signs


def dominance_matrix(F: np.ndarray) -> np.ndarray:
    """D[i, j] is True when row i dominates row j. Shape (n, n)."""
    no_worse = np.all(F[:, None, :] <= F[None, :, :], axis=2)
    better = np.any(F[:, None, :] < F[None, :, :], axis=2)
    return no_worse & better


def non_dominated_sort(F: np.ndarray) -> np.ndarray:
    """Front rank of every row, shape (n,) int: 0 for the non-dominated, 1 for those dominated
    only by rank-0 rows, and so on."""
    F = np.asarray(F, dtype=float)
    dominates = dominance_matrix(F)
    dominated_by = dominates.sum(axis=0)  # how many rows dominate each row
    ranks = np.full(len(F), -1, dtype=int)
    rank = 0
    current = np.flatnonzero(dominated_by == 0)
    while current.size:
        ranks[current] = rank
        dominated_by = dominated_by - dominates[current].sum(axis=0)
        dominated_by[ranks >= 0] = -1
        current = np.flatnonzero(dominated_by == 0)
        rank += 1
    return ranks


def crowding_distance(F: np.ndarray) -> np.ndarray:
    """NSGA-II crowding distance of each row within the set F, shape (n,).

    Per objective, rows are sorted; the two extremes get +inf, others the gap between their
    neighbours divided by the objective's range; the per-objective parts are summed. An
    objective with zero range contributes 0 (extremes included); n <= 2 gives all +inf.
    """
    F = np.asarray(F, dtype=float)
    n, m = F.shape
    if n <= 2:
        return np.full(n, np.inf)
    distance = np.zeros(n)
    for column in range(m):
        order = np.argsort(F[:, column], kind="stable")
        values = F[order, column]
        span = values[-1] - values[0]
        if span <= 0:
            continue
        distance[order[1:-1]] += (values[2:] - values[:-2]) / span
        distance[order[[0, -1]]] = np.inf
    return distance


def select_survivors(F: np.ndarray, k: int, valid: np.ndarray | None = None) -> np.ndarray:
    """Indices of the k rows kept: whole fronts in rank order, the front that does not fit
    cut by crowding distance (largest first), remaining ties by lower index.

    ``valid`` (n,) bool: invalid rows (failed evaluations) rank behind every valid row and
    among themselves by index. Returns indices sorted ascending.
    """
    F = np.asarray(F, dtype=float)
    n = len(F)
    valid = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    ranks = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
    good = np.flatnonzero(valid)
    if good.size:
        ranks[good] = non_dominated_sort(F[good])
    crowding = np.zeros(n)
    for rank in np.unique(ranks[good]):
        members = good[ranks[good] == rank]
        crowding[members] = crowding_distance(F[members])
    order = np.lexsort((np.arange(n), -crowding, ranks))
    return np.sort(order[:k])


def dominance_counts(F: np.ndarray) -> np.ndarray:
    """How many rows dominate each row, shape (n,) int, as evosoro counts them
    (softbot.py:515-539, ``calc_dominance``): a row identical to row i on every objective
    counts as dominating it when it comes later (a newer individual, rows in id order), so
    of identical twins the newest is the one not dominated."""
    F = np.asarray(F, dtype=float)
    equal = np.all(F[:, None, :] == F[None, :, :], axis=2)
    newer = np.arange(len(F))[:, None] > np.arange(len(F))[None, :]
    return (dominance_matrix(F) | (equal & newer)).sum(axis=0)


def evosoro_order(F: np.ndarray, levels: np.ndarray, ages: np.ndarray) -> np.ndarray:
    """Row indices in evosoro's ``sort_by_objectives`` order (softbot.py:478-493): by level,
    then by each objective in declared order (the first most important), then younger age,
    then later index (newer individual)."""
    F = np.asarray(F, dtype=float)
    n = len(F)
    keys = (-np.arange(n), np.asarray(ages, dtype=float)) + tuple(F[:, ::-1].T) + (levels,)
    return np.lexsort(keys)


def log_biased_pick(level_size: int, draw: float) -> int:
    """The position (1 .. level_size - 1) evosoro picks in a sorted level from a uniform
    ``draw`` in [0, 1): the i with log(i) / log(L) <= draw < log(i + 1) / log(L), that is
    floor(L ** draw); position i has chance log((i + 1) / i) / log(L), so better-sorted
    members are likelier (tools/selection.py:52-61)."""
    return min(max(int(np.floor(level_size**draw)), 1), level_size - 1)


def evosoro_survivors(
    F: np.ndarray,
    k: int,
    ages: np.ndarray,
    rng: np.random.Generator,
    valid: np.ndarray | None = None,
) -> np.ndarray:
    """Indices of the k rows kept by evosoro's ``pareto_selection``, rows in id order.

    Levels are dominance counts (:func:`dominance_counts`; invalid rows, failed evaluations,
    come after every valid one, as evosoro's ``2 * pop_size`` extra dominators put them).
    Whole levels are taken in increasing order while they fit; of the level that does not
    fit (sorted by :func:`evosoro_order`) the first member is taken, then members at
    positions :func:`log_biased_pick` of uniform draws from ``rng`` (a position already
    taken draws again) until k are kept. Returns indices sorted ascending.
    """
    F = np.asarray(F, dtype=float)
    n = len(F)
    valid = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    levels = np.zeros(n, dtype=np.int64)
    for group, offset in ((valid, 0), (~valid, n)):
        members = np.flatnonzero(group)
        levels[members] = dominance_counts(F[members]) + offset
    order = evosoro_order(F, levels, ages)
    kept: list[int] = []
    for level in np.unique(levels):
        members = [int(i) for i in order if levels[i] == level]
        room = k - len(kept)
        if room <= 0:
            break
        if len(members) <= room:
            kept.extend(members)
            continue
        chosen = {0}
        while len(chosen) < room:
            chosen.add(log_biased_pick(len(members), float(rng.random())))
        kept.extend(members[i] for i in sorted(chosen))
    return np.sort(np.array(kept, dtype=np.int64))
