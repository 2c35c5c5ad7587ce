import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from softevo.evolution.selection import (
    Objective,
    crowding_distance,
    non_dominated_sort,
    objective_matrix,
    select_survivors,
)


def dominates(a, b):
    return all(x <= y for x, y in zip(a, b, strict=True)) and any(
        x < y for x, y in zip(a, b, strict=True)
    )


def brute_force_ranks(F):
    """Peel fronts by definition: a front is the rows no remaining row dominates."""
    remaining = list(range(len(F)))
    ranks = [None] * len(F)
    rank = 0
    while remaining:
        front = [i for i in remaining if not any(dominates(F[j], F[i]) for j in remaining)]
        for i in front:
            ranks[i] = rank
        remaining = [i for i in remaining if i not in front]
        rank += 1
    return ranks


def brute_force_crowding(F):
    n, m = F.shape
    if n <= 2:
        return [float("inf")] * n
    out = [0.0] * n
    for k in range(m):
        order = sorted(range(n), key=lambda i: (F[i, k], i))
        span = F[order[-1], k] - F[order[0], k]
        if span == 0:
            continue
        out[order[0]] = out[order[-1]] = float("inf")
        for pos in range(1, n - 1):
            out[order[pos]] += (F[order[pos + 1], k] - F[order[pos - 1], k]) / span
    return out


matrices = st.integers(1, 25).flatmap(
    lambda n: st.integers(1, 4).flatmap(
        lambda m: arrays(np.float64, (n, m), elements=st.integers(-3, 3).map(float))
    )
)


@settings(max_examples=200, deadline=None)
@given(F=matrices)
def test_non_dominated_sort_matches_brute_force(F):
    assert list(non_dominated_sort(F)) == brute_force_ranks(F)


@settings(max_examples=200, deadline=None)
@given(F=matrices)
def test_crowding_matches_brute_force(F):
    assert np.allclose(crowding_distance(F), brute_force_crowding(F))


@settings(max_examples=100, deadline=None)
@given(F=matrices, data=st.data())
def test_survivors_take_whole_fronts_first(F, data):
    k = data.draw(st.integers(1, len(F)))
    kept = select_survivors(F, k)
    assert len(kept) == k and len(set(kept)) == k
    ranks = non_dominated_sort(F)
    worst_kept = ranks[kept].max()
    dropped = np.setdiff1d(np.arange(len(F)), kept)
    assert np.all(ranks[dropped] >= worst_kept)


def test_invalid_rows_rank_behind_valid_ones():
    F = np.array([[0.0, 0.0], [5.0, 5.0], [6.0, 6.0]])
    kept = select_survivors(F, 2, valid=np.array([False, True, True]))
    assert list(kept) == [1, 2]


def test_objective_matrix_is_in_minimisation_form():
    objectives = (Objective("distance", "max"), Objective("voxel_count", "min"))
    F = objective_matrix([{"distance": 2.0, "voxel_count": 10}], objectives)
    assert F.tolist() == [[-2.0, 10.0]]
