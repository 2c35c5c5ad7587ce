import numpy as np
import pytest
from scipy import stats as scipy_stats

from softevo.evolution.stats import bonferroni, bootstrap_ci, mann_whitney


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
