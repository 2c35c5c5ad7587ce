"""What a finding's design can decide: power of the Jonckheere-Terpstra trend test and of the
two-sided Mann-Whitney test by simulation, the runs a treatment a design needs, bootstrap
intervals of A12 and Holm's step-down thresholds. Pure functions of arrays, seeded: the same
call gives the same answer.

The model (``Effect``): each group's run values are normal, group i with mean ``means[i]``
and standard deviation ``spreads[i]``; the groups are in the order the hypothesis says the
values rise. Two effects are asked of every finding:

- the effect seen: each group at its observed mean and spread (``observed_effect``);
- a reference effect of A12 ``REFERENCE_A12`` (0.71, Vargha and Delaney's "large"): a linear
  trend of common spread whose extreme groups differ by A12 = 0.71 (for two groups, a shift
  of that A12; ``linear_effect``).

Power is the share of ``RESAMPLES`` simulated studies of n runs a group whose test rejects
at level alpha. The trend's critical J comes from the exact null without ties (``analysis.
rank_tests.jt_null``) up to ``EXACT_MAX_RUNS`` runs in all, from its normal approximation
beyond; a two-sided Mann-Whitney test rejects when U is at least as far from its mean as the
critical distance, split evenly between the tails. The draws of a study of n runs are common
to every effect (seeded by n), so the power rises with the effect at each n.

``runs_needed``: the smallest n (runs a group) with power >= ``POWER``, searched by doubling
then bisection up to ``MAX_RUNS``; None beyond. ``a12_interval``: the percentile bootstrap
95% interval of A12, runs resampled within each group. ``holm_thresholds``: the level
Holm's step-down procedure holds each test to, alpha / (m - rank), by rank of p.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import stats

from softevo.analysis.rank_tests import jt_null
from softevo.evolution.stats import vargha_delaney

ALPHA = 0.05
POWER = 0.8
REFERENCE_A12 = 0.71
RESAMPLES = 2_000
BOOTSTRAP = 4_000
MAX_RUNS = 4_000
MIN_RESAMPLES = 200
MAX_DRAWS = 1_000_000
EXACT_MAX_RUNS = 60
SEED = 20261207


@dataclass(frozen=True)
class Effect:
    """Normal run values per group, in the order the hypothesis says they rise."""

    means: tuple[float, ...]
    spreads: tuple[float, ...]

    @property
    def groups(self) -> int:
        return len(self.means)


def observed_effect(groups: Sequence[np.ndarray]) -> Effect:
    """Each group at its own mean and standard deviation (ddof 1; 0 for a single run)."""
    arrays = [np.asarray(g, float) for g in groups]
    return Effect(tuple(float(a.mean()) for a in arrays),
                  tuple(float(a.std(ddof=1)) if a.size > 1 else 0.0 for a in arrays))


def linear_effect(groups: int, a12: float = REFERENCE_A12) -> Effect:
    """A linear trend over ``groups`` groups of spread 1 whose extreme groups differ by
    ``a12`` (A12 = Phi(shift / sqrt 2) between two normal samples)."""
    shift = math.sqrt(2.0) * float(stats.norm.ppf(a12))
    return Effect(tuple(shift * i / (groups - 1) for i in range(groups)), (1.0,) * groups)


# ---- the statistics of many simulated studies at once -----------------------------------------
def jt_statistics(draws: np.ndarray) -> np.ndarray:
    """J of each study of ``draws`` (R, groups, n) without ties (continuous draws): over the
    study's values in ascending order, each value counts the earlier values of a lower group."""
    studies_, groups, n = draws.shape
    order = draws.reshape(studies_, groups * n).argsort(axis=1, kind="stable")
    labels = np.repeat(np.arange(groups), n)[order]  # the group of each value, in ascending order
    total = np.zeros(studies_)
    for group in range(1, groups):
        lower_before = np.cumsum(labels < group, axis=1)  # at a value of ``group``: the lower ones before it
        total += np.where(labels == group, lower_before, 0).sum(axis=1)
    return total


@lru_cache(maxsize=512)
def jt_critical(groups: int, n: int, alpha: float) -> float:
    """The smallest J whose one-sided upper p (no ties) is at most ``alpha``, for ``groups``
    groups of n runs (inf when none is)."""
    if groups * n <= EXACT_MAX_RUNS:
        pmf = jt_null([n] * groups)
        upper = np.cumsum(pmf[::-1])[::-1]  # P(J >= j)
        feasible = np.flatnonzero(upper <= alpha * (1 + 1e-9))
        return float(feasible[0]) if feasible.size else math.inf
    total = groups * n
    mean = (total**2 - groups * n**2) / 4
    variance = (total * (total - 1) * (2 * total + 5) - groups * n * (n - 1) * (2 * n + 5)) / 72
    return mean + float(stats.norm.isf(alpha)) * math.sqrt(variance)


def studies(groups: int, n: int, resamples: int = RESAMPLES) -> int:
    """How many studies a power estimate simulates at n runs a group: ``resamples``, fewer
    for large studies (at least ``MIN_RESAMPLES``), so that one estimate draws at most
    ``MAX_DRAWS`` values (its standard error stays below 0.03 near 80% power)."""
    return max(MIN_RESAMPLES, min(resamples, MAX_DRAWS // (groups * n)))


@lru_cache(maxsize=16)
def _standard_draws(groups: int, n: int, resamples: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng([seed, groups, n])
    return rng.standard_normal((resamples, groups, n))


def power(effect: Effect, n: int, alpha: float, two_sided: bool = False,
          resamples: int = RESAMPLES, seed: int = SEED) -> float:
    """The share of simulated studies of ``n`` runs a group that reject at ``alpha``: the
    one-sided trend test (two-sided Mann-Whitney of two groups with ``two_sided``)."""
    if n < 2:
        return 0.0
    base = _standard_draws(effect.groups, n, studies(effect.groups, n, resamples), seed)
    draws = base * np.asarray(effect.spreads)[None, :, None] + np.asarray(effect.means)[None, :, None]
    if effect.spreads == (0.0,) * effect.groups:  # no spread: the order is certain
        draws = draws + 1e-12 * base
    j = jt_statistics(draws)
    if not two_sided:
        return float(np.mean(j >= jt_critical(effect.groups, n, alpha)))
    if effect.groups != 2:
        raise ValueError("a two-sided test compares two groups")
    half = jt_critical(2, n, alpha / 2)  # the upper tail; the lower mirrors it about n^2 / 2
    return float(np.mean((j >= half) | (j <= n * n - half)))


def runs_needed(effect: Effect, alpha: float, two_sided: bool = False, target: float = POWER,
                max_runs: int = MAX_RUNS, resamples: int = RESAMPLES) -> int | None:
    """The smallest n (runs a group) whose ``power`` reaches ``target`` (None up to
    ``max_runs``); doubling from 2, then bisection."""
    def enough(n: int) -> bool:
        return power(effect, n, alpha, two_sided, resamples) >= target

    low, high = 1, 2
    while not enough(high):
        if high >= max_runs:
            return None
        low, high = high, min(2 * high, max_runs)
    while high - low > 1:
        middle = (low + high) // 2
        low, high = (low, middle) if enough(middle) else (middle, high)
    return high


def detectable_a12(groups: int, n: int, alpha: float, two_sided: bool = False, target: float = POWER,
                   resamples: int = RESAMPLES) -> float:
    """The smallest extreme-group A12 of a linear trend (a shift of two groups) that ``n``
    runs a group detect with ``target`` power; NaN when even a near-certain order is not
    (the test's floor)."""
    def enough(a12: float) -> bool:
        return power(linear_effect(groups, a12), n, alpha, two_sided, resamples) >= target

    if not enough(0.9999):
        return math.nan
    low, high = 0.5, 0.9999
    while high - low > 0.0025:
        middle = (low + high) / 2
        low, high = (low, middle) if enough(middle) else (middle, high)
    return high


# ---- intervals and thresholds -----------------------------------------------------------------
def a12_interval(high: np.ndarray, low: np.ndarray, level: float = 0.95, resamples: int = BOOTSTRAP,
                 seed: int = SEED) -> tuple[float, float]:
    """The percentile bootstrap ``level`` interval of A12 of ``high`` over ``low``, runs
    resampled with replacement within each group (NaN, NaN for an empty group)."""
    high, low = np.asarray(high, float), np.asarray(low, float)
    if not (high.size and low.size):
        return math.nan, math.nan
    rng = np.random.default_rng([seed, high.size, low.size])
    a = high[rng.integers(0, high.size, (resamples, high.size))]
    b = low[rng.integers(0, low.size, (resamples, low.size))]
    greater = (a[:, :, None] > b[:, None, :]).mean(axis=(1, 2))
    equal = (a[:, :, None] == b[:, None, :]).mean(axis=(1, 2))
    values = greater + 0.5 * equal
    tail = (1 - level) / 2
    return float(np.quantile(values, tail)), float(np.quantile(values, 1 - tail))


def holm_thresholds(p_values: Sequence[float], alpha: float = ALPHA) -> np.ndarray:
    """The level Holm's step-down procedure holds each p to: alpha / (m - rank) by rank of p
    (rank 0 the smallest); NaN for a NaN p, which does not count in m."""
    p = np.asarray(p_values, float)
    out = np.full(p.shape, np.nan)
    valid = np.flatnonzero(np.isfinite(p))
    order = valid[np.argsort(p[valid], kind="stable")]
    for rank, index in enumerate(order):
        out[index] = alpha / (order.size - rank)
    return out


def adjacent_a12s(groups: Sequence[np.ndarray]) -> list[float]:
    """A12 of each group over the one before it (the order the hypothesis says values rise)."""
    return [vargha_delaney(b, a) if len(a) and len(b) else math.nan
            for a, b in zip(groups[:-1], groups[1:], strict=True)]
