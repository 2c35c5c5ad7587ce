"""analysis.design: the vectorized statistics against slow obvious versions, the power
simulation against what the tests' nulls promise, intervals and Holm's thresholds."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from softevo.analysis import design
from softevo.analysis.rank_tests import holm, jonckheere_terpstra, jt_statistic
from softevo.evolution.stats import vargha_delaney


def test_jt_statistics_of_many_studies_equal_the_pairwise_count():
    rng = np.random.default_rng(3)
    draws = rng.standard_normal((40, 4, 6)) + 0.4 * np.arange(4)[None, :, None]
    slow = [jt_statistic([draws[r, g] for g in range(4)]) for r in range(40)]
    assert design.jt_statistics(draws).tolist() == slow


@pytest.mark.parametrize("groups,n", [(2, 6), (4, 6), (5, 6), (3, 25)])
def test_the_critical_value_holds_the_level(groups, n):
    alpha = 0.05 / 6
    size = design.power(design.Effect((0.0,) * groups, (1.0,) * groups), n, alpha, resamples=4000)
    assert size <= alpha + 3 * math.sqrt(alpha / 4000) + 0.002  # the test's size under the null


def test_power_under_the_null_is_the_level_for_the_exact_and_the_normal_critical_values():
    for groups, n in ((4, 6), (4, 40)):
        size = design.power(design.Effect((0.0,) * groups, (1.0,) * groups), n, 0.05, resamples=4000)
        assert abs(size - 0.05) < 0.025, (groups, n, size)


def test_two_sided_power_under_the_null_counts_both_tails():
    size = design.power(design.Effect((0.0, 0.0), (1.0, 1.0)), 30, 0.05, two_sided=True, resamples=4000)
    assert abs(size - 0.05) < 0.02
    # a shift either way is detected alike
    up = design.power(design.Effect((0.0, 1.0), (1.0, 1.0)), 10, 0.05, two_sided=True)
    down = design.power(design.Effect((1.0, 0.0), (1.0, 1.0)), 10, 0.05, two_sided=True)
    assert up == pytest.approx(down, abs=0.05) and up > 0.4


def test_power_rises_with_the_effect_and_with_n():
    a = design.power(design.linear_effect(4, 0.6), 6, 0.01)
    b = design.power(design.linear_effect(4, 0.8), 6, 0.01)
    c = design.power(design.linear_effect(4, 0.8), 20, 0.01)
    assert a < b < c


def test_runs_needed_is_the_smallest_n_reaching_the_target():
    effect = design.linear_effect(2, 0.71)
    n = design.runs_needed(effect, 0.05, two_sided=True)
    assert design.power(effect, n, 0.05, True) >= 0.8 > design.power(effect, n - 1, 0.05, True)
    assert 25 <= n <= 35  # the textbook figure for A12 0.71 (d = 0.78) is about 27-30 per group
    assert design.runs_needed(design.Effect((1.0, 0.0), (1.0, 1.0)), 0.05, max_runs=64) is None  # reversed


def test_a_trend_detects_less_than_its_extreme_pair():
    """Jonckheere-Terpstra with 4 x 6 runs detects a smaller extreme-level A12 under a linear
    trend than a Mann-Whitney test of the two extreme groups alone."""
    alpha = 0.05 / 6
    trend = design.detectable_a12(4, 6, alpha)
    pair = design.detectable_a12(2, 6, 2 * alpha)  # one-sided at alpha
    assert 0.85 < trend < pair < 1.0


def test_the_bootstrap_interval_holds_the_estimate_and_narrows_with_n():
    rng = np.random.default_rng(5)
    a, b = rng.normal(0.5, 1, 6), rng.normal(0, 1, 6)
    low, high = design.a12_interval(a, b)
    assert low <= vargha_delaney(a, b) <= high
    a2, b2 = rng.normal(0.5, 1, 60), rng.normal(0, 1, 60)
    low2, high2 = design.a12_interval(a2, b2)
    assert high2 - low2 < high - low
    assert design.a12_interval(a, b) == (low, high)  # seeded
    assert all(math.isnan(v) for v in design.a12_interval(a, []))


def test_holm_thresholds_step_down_by_rank():
    p = [0.03, 0.001, float("nan"), 0.2]
    thresholds = design.holm_thresholds(p, 0.05)
    assert thresholds[1] == pytest.approx(0.05 / 3) and thresholds[0] == pytest.approx(0.05 / 2)
    assert thresholds[3] == pytest.approx(0.05) and math.isnan(thresholds[2])
    # a p below its threshold at every step up to it is what Holm's adjusted p < alpha means
    adjusted = holm(p)
    for k, (pk, _tk) in enumerate(zip(p, thresholds, strict=True)):
        if math.isfinite(pk):
            earlier = [i for i in range(len(p)) if math.isfinite(p[i]) and p[i] <= pk]
            assert (adjusted[k] < 0.05) == all(p[i] < thresholds[i] for i in earlier)


def test_exact_critical_value_matches_the_rank_tests_p():
    """At the critical J the exact one-sided p is at most alpha; one below it, above."""
    groups, n, alpha = 3, 4, 0.05
    critical = design.jt_critical(groups, n, alpha)
    seen = {}
    for perm in itertools.islice(itertools.permutations(range(groups * n)), 0, 200000, 7):
        data = [np.array(perm[g * n:(g + 1) * n], float) for g in range(groups)]
        j = jt_statistic(data)
        if j in (critical, critical - 1) and j not in seen:
            seen[j] = jonckheere_terpstra(data).p
        if len(seen) == 2:
            break
    assert seen[critical] <= alpha < seen[critical - 1]
