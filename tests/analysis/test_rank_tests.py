"""Rank tests against brute-force permutation, scipy and known reference values."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

from softevo.analysis.rank_tests import (
    EXACT,
    NORMAL,
    _jt_moments,
    holm,
    jonckheere_terpstra,
    jt_null,
    jt_statistic,
    mann_whitney,
    mann_whitney_null,
)


def _assignments(values: np.ndarray, sizes: tuple[int, ...]):
    """Every split of ``values`` into groups of ``sizes`` (each distinct labelling once)."""
    labels = [k for k, size in enumerate(sizes) for _ in range(size)]
    for order in set(itertools.permutations(labels)):
        order = np.array(order)
        yield [values[order == k] for k in range(len(sizes))]


def _permutation_p(groups, alternative="increasing") -> float:
    """The permutation p of J: the share of labellings with J at least (at most) the one seen."""
    values = np.concatenate(groups)
    observed = jt_statistic(groups)
    found = [jt_statistic(g) for g in _assignments(values, tuple(len(g) for g in groups))]
    found = np.array(found)
    if alternative == "increasing":
        return float(np.mean(found >= observed - 1e-9))
    return float(np.mean(found <= observed + 1e-9))


@pytest.mark.parametrize("sizes", [(2, 2, 2), (1, 3, 2), (3, 2, 2), (2, 1, 1, 2)])
def test_the_exact_jt_p_is_the_permutation_p(sizes):
    rng = np.random.default_rng(sum(sizes))
    groups = [rng.normal(k * 0.5, 1, size) for k, size in enumerate(sizes)]
    for alternative in ("increasing", "decreasing"):
        result = jonckheere_terpstra(groups, alternative)
        assert result.method == EXACT
        assert result.p == pytest.approx(_permutation_p(groups, alternative))


def test_the_jt_null_is_the_permutation_distribution_of_j():
    sizes = (2, 3, 2)
    values = np.arange(7.0)
    found = [jt_statistic(g) for g in _assignments(values, sizes)]
    counts = np.bincount(np.array(found, int), minlength=17) / len(found)
    assert jt_null(sizes) == pytest.approx(counts)


def test_known_reference_values():
    # singletons: J counts the non-inversions of a random permutation, whose counts are the
    # Mahonian numbers (OEIS A008302): 1 3 5 6 5 3 1 for n = 4
    assert jt_null([1, 1, 1, 1]) * 24 == pytest.approx([1, 3, 5, 6, 5, 3, 1])
    # perfectly ordered groups: J is at its maximum, p = 1 / multinomial(9; 3, 3, 3) = 1/1680
    groups = [[1, 2, 3], [4, 5, 6], [7, 8, 9]]
    assert jonckheere_terpstra(groups).p == pytest.approx(1 / 1680)
    assert jonckheere_terpstra(groups).statistic == 27
    assert jonckheere_terpstra(groups, "decreasing").p == pytest.approx(1.0)
    # two groups: the exact Mann-Whitney distribution (Gaussian binomial coefficients)
    assert mann_whitney_null(2, 2) * 6 == pytest.approx([1, 1, 2, 1, 1])


def test_two_groups_are_scipys_exact_mann_whitney():
    a, b = [1.1, 2.3, 2.9, 4.0, 5.2, 3.3], [3.4, 6.1, 7.7, 8.0, 9.5, 10.2, 4.4]
    for alternative in ("less", "greater", "two-sided"):
        reference = stats.mannwhitneyu(a, b, alternative=alternative, method="exact")
        result = mann_whitney(a, b, alternative)
        assert (result.statistic, result.p) == pytest.approx((reference.statistic, reference.pvalue))
        assert result.method == EXACT


def test_ties_use_the_tie_corrected_normal_approximation():
    a, b = [1, 2, 2, 3, 4], [2, 3, 5, 5, 6, 7]
    result = mann_whitney(a, b, "less")
    reference = stats.mannwhitneyu(a, b, alternative="less", method="asymptotic", use_continuity=False)
    assert result.method == NORMAL
    assert (result.statistic, result.p) == pytest.approx((reference.statistic, reference.pvalue))


def test_the_tie_corrected_variance_is_the_permutation_variance():
    groups = [np.array([1.0, 2, 2]), np.array([2.0, 3]), np.array([3.0, 3, 4])]
    values = np.concatenate(groups)
    found = np.array([jt_statistic(g) for g in _assignments(values, (3, 2, 3))])
    _, ties = np.unique(values, return_counts=True)
    mean, variance = _jt_moments(np.array([3.0, 2, 3]), ties.astype(float))
    assert (mean, variance) == pytest.approx((found.mean(), found.var()))


def test_a_falling_trend_is_an_increasing_one_reversed_and_edge_cases():
    groups = [[5.0, 6.1, 7.2], [3.3, 4.4], [0.5, 1.6, 2.7]]
    assert jonckheere_terpstra(groups, "decreasing").p == pytest.approx(jonckheere_terpstra(groups[::-1]).p)
    assert math.isnan(jonckheere_terpstra([[1.0, 2.0], []]).p)
    assert jonckheere_terpstra([[1.0, 1.0], [1.0, 1.0]]).p == 1.0


def test_holm_steps_down_and_keeps_order():
    adjusted = holm([0.01, 0.04, 0.03, np.nan, 0.005])
    assert adjusted[:3] == pytest.approx([0.03, 0.06, 0.06]) and adjusted[4] == pytest.approx(0.02)
    assert np.isnan(adjusted[3])
    assert holm([0.2, 0.3]) == pytest.approx([0.4, 0.4])
