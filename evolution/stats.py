"""Statistics for comparing treatments (paper section 2.5): bootstrap confidence intervals of
the mean and of a difference of means, Mann-Whitney U tests, the Vargha-Delaney A12 effect
size and the Bonferroni correction. Pure functions of arrays."""

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


def vargha_delaney(a: Sequence[float], b: Sequence[float]) -> float:
    """Vargha-Delaney A12 of ``a`` over ``b``: P(X > Y) + P(X = Y) / 2 for X drawn from
    ``a`` and Y from ``b`` (0.5: no effect; 1: every a above every b). Equals U_a / (n_a n_b).
    An empty input raises ValueError."""
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if x.size == 0 or y.size == 0:
        raise ValueError("vargha_delaney needs at least one value in each sample")
    greater = (x[:, None] > y[None, :]).sum()
    equal = (x[:, None] == y[None, :]).sum()
    return float((greater + 0.5 * equal) / (x.size * y.size))


def bootstrap_difference(
    a: Sequence[float],
    b: Sequence[float],
    rng: np.random.Generator,
    confidence: float = 0.95,
    n_resamples: int = 10_000,
) -> tuple[float, float, float]:
    """(mean(a) - mean(b), low, high): percentile bootstrap interval of the difference of
    means, each sample resampled with replacement on its own (``n_resamples`` times, ``a``
    drawn before ``b``). An empty input raises ValueError."""
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if x.size == 0 or y.size == 0:
        raise ValueError("bootstrap_difference needs at least one value in each sample")
    means_x = x[rng.integers(0, x.size, (n_resamples, x.size))].mean(axis=1)
    means_y = y[rng.integers(0, y.size, (n_resamples, y.size))].mean(axis=1)
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(means_x - means_y, [tail, 1.0 - tail])
    return float(x.mean() - y.mean()), float(low), float(high)
