"""Statistics for comparing treatments (paper section 2.5): bootstrap confidence intervals of
the mean, Mann-Whitney U tests and the Bonferroni correction. Pure functions of arrays."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy import stats


def bootstrap_ci(
    values: Sequence[float],
    rng: np.random.Generator,
    confidence: float = 0.95,
    n_resamples: int = 10_000,
) -> tuple[float, float, float]:
    """(mean, low, high): percentile bootstrap confidence interval of the mean.

    ``n_resamples`` resamples of len(values) drawn with replacement; the interval is the
    (1 - confidence)/2 and (1 + confidence)/2 quantiles of their means. One value gives a
    zero-width interval; an empty input raises ValueError.
    """
    data = np.asarray(values, dtype=float)
    if data.size == 0:
        raise ValueError("bootstrap_ci needs at least one value")
    means = data[rng.integers(0, data.size, (n_resamples, data.size))].mean(axis=1)
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(means, [tail, 1.0 - tail])
    return float(data.mean()), float(low), float(high)


def mann_whitney(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """(U statistic of ``a``, two-sided p-value) of the Mann-Whitney U test (scipy)."""
    result = stats.mannwhitneyu(np.asarray(a, float), np.asarray(b, float), alternative="two-sided")
    return float(result.statistic), float(result.pvalue)


def bonferroni(p_values: Sequence[float]) -> np.ndarray:
    """Bonferroni-adjusted p-values: each times the number of comparisons, capped at 1."""
    p = np.asarray(p_values, dtype=float)
    return np.minimum(p * p.size, 1.0)
