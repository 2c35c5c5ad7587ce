import numpy as np
import pytest
from scipy import stats as scipy_stats

from softevo.evolution.stats import (
    bonferroni,
    bootstrap_ci,
    bootstrap_difference,
    mann_whitney,
    vargha_delaney,
)


def test_bootstrap_ci_brackets_the_mean_and_matches_scipy():
    rng = np.random.default_rng(0)
    values = rng.normal(10.0, 2.0, 40)
    mean, low, high = bootstrap_ci(values, np.random.default_rng(1), n_resamples=20_000)
    assert mean == pytest.approx(values.mean())
    assert low < mean < high
    reference = scipy_stats.bootstrap(
        (values,),
        np.mean,
        confidence_level=0.95,
        method="percentile",
        n_resamples=20_000,
        rng=np.random.default_rng(2),
    ).confidence_interval
    assert low == pytest.approx(reference.low, abs=0.1)
    assert high == pytest.approx(reference.high, abs=0.1)
    assert bootstrap_ci([3.0], np.random.default_rng(0)) == (3.0, 3.0, 3.0)
    with pytest.raises(ValueError):
        bootstrap_ci([], np.random.default_rng(0))


def test_mann_whitney_matches_scipy():
    a, b = [1.0, 2.0, 3.0, 4.0, 5.0], [3.5, 6.0, 7.0, 8.0, 9.0, 10.0]
    u, p = mann_whitney(a, b)
    ref = scipy_stats.mannwhitneyu(a, b, alternative="two-sided")
    assert u == ref.statistic and p == pytest.approx(ref.pvalue)
    assert u == 2.0  # hand count: only 4 > 3.5 and 5 > 3.5 among the 30 pairs


def test_bonferroni_multiplies_and_caps():
    assert bonferroni([0.01, 0.2, 0.5]).tolist() == pytest.approx([0.03, 0.6, 1.0])


def test_vargha_delaney_by_hand_and_from_u():
    # a = [1, 2, 3] against b = [2, 4]: of the 6 pairs only (3, 2) has a above b and (2, 2)
    # ties, so A12 = (1 + 0.5) / 6
    assert vargha_delaney([1, 2, 3], [2, 4]) == pytest.approx(0.25)
    assert vargha_delaney([2, 4], [1, 2, 3]) == pytest.approx(0.75)
    assert vargha_delaney([5, 6], [1, 2, 3]) == 1.0 and vargha_delaney([1, 1], [1]) == 0.5
    a, b = [1.0, 2.0, 3.0, 4.0, 5.0], [3.5, 6.0, 7.0, 8.0, 9.0, 10.0]
    assert vargha_delaney(a, b) == pytest.approx(mann_whitney(a, b)[0] / 30)
    with pytest.raises(ValueError):
        vargha_delaney([], [1.0])


def test_bootstrap_difference_by_hand():
    # means of resamples of [0, 1]: 0 (1/4), 0.5 (1/2), 1 (1/4); b = [5] never varies, so
    # the difference is -5, -4.5 or -4 and its 95% interval spans the two extremes
    diff, low, high = bootstrap_difference([0.0, 1.0], [5.0], np.random.default_rng(0))
    assert (diff, low, high) == (-4.5, -5.0, -4.0)
    # a 40% interval (quantiles 0.3 and 0.7) lies in the middle atom
    assert bootstrap_difference([0.0, 1.0], [5.0], np.random.default_rng(0), 0.4) == (-4.5, -4.5, -4.5)
    assert bootstrap_difference([3.0, 3.0], [1.0], np.random.default_rng(0)) == (2.0, 2.0, 2.0)


def test_bootstrap_difference_is_seeded():
    rng = np.random.default_rng(5)
    a, b = rng.normal(0, 1, 12), rng.normal(1, 1, 9)
    first = bootstrap_difference(a, b, np.random.default_rng(3), n_resamples=2_000)
    assert first == bootstrap_difference(a, b, np.random.default_rng(3), n_resamples=2_000)
    assert first != bootstrap_difference(a, b, np.random.default_rng(4), n_resamples=2_000)
    assert first[1] < first[0] < first[2]
    with pytest.raises(ValueError):
        bootstrap_difference([1.0], [], np.random.default_rng(0))
