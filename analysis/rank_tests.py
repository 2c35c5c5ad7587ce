"""Rank tests of ordered alternatives and of two samples, with exact p-values where the data
have no ties, and Holm's step-down correction. Pure functions of arrays.

- ``jonckheere_terpstra(groups)``: the Jonckheere-Terpstra test that values rise along the
  groups as given (one-sided; pass the groups in the order the hypothesis says they rise,
  reversed for a falling trend). J = sum over group pairs i < j of #(x_i < x_j) + #(x_i =
  x_j) / 2. Without ties its p is exact: under the null every assignment of the pooled
  values to the groups is equally likely, and J's distribution is the convolution of
  Mann-Whitney U distributions, group by group (``jt_null``; the q-multinomial coefficient
  of MacMahon). With ties: the normal approximation with the tie-corrected variance
  (Hollander & Wolfe 1999, eq. 6.19), no continuity correction.
- ``mann_whitney(a, b)``: the same test of two groups (J = U of b over a), one- or
  two-sided; the exact p uses the same null.
- ``holm(p)``: Holm's step-down adjusted p-values (monotone, capped at 1).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import stats

EXACT = "exact"
NORMAL = "normal approximation, tie-corrected"


@dataclass(frozen=True)
class RankTest:
    """A rank test's outcome: the statistic, its p-value and how p was computed (``EXACT``
    or ``NORMAL``)."""

    statistic: float
    p: float
    method: str


@lru_cache(maxsize=256)
def mann_whitney_null(m: int, n: int) -> np.ndarray:
    """P(U = u), u = 0..m n, for U = #(x < y) of m x's and n y's drawn at random without
    ties (recursion of Mann & Whitney 1947: the largest value is a y with probability n /
    (m + n), and then exceeds every x)."""
    rows = [np.ones(1)] * (n + 1)  # rows[j]: the distribution for (i, j), current i; i = 0: U = 0
    for i in range(1, m + 1):
        new = [np.ones(1)]  # j = 0: U = 0
        for j in range(1, n + 1):
            pmf = np.zeros(i * j + 1)
            pmf[i:] += j / (i + j) * new[j - 1]  # largest is a y: + i pairs
            pmf[: rows[j].size] += i / (i + j) * rows[j]  # largest is an x
            new.append(pmf)
        rows = new
    return rows[n]


def jt_null(sizes: Sequence[int]) -> np.ndarray:
    """P(J = j), j = 0..sum over i < k of n_i n_k, of the Jonckheere-Terpstra statistic for
    groups of ``sizes`` without ties: the convolution of U(n_1 + .. + n_{k-1}, n_k) over k."""
    pmf, before = np.ones(1), 0
    for size in sizes:
        pmf = np.convolve(pmf, mann_whitney_null(before, int(size)))
        before += int(size)
    return pmf / pmf.sum()


def jt_statistic(groups: Sequence[np.ndarray]) -> float:
    """J = sum over i < k of #(x_i < x_k) + #(x_i = x_k) / 2."""
    total = 0.0
    for i, low in enumerate(groups):
        for high in groups[i + 1 :]:
            total += (low[:, None] < high[None, :]).sum() + 0.5 * (low[:, None] == high[None, :]).sum()
    return float(total)


def _jt_moments(sizes: np.ndarray, ties: np.ndarray) -> tuple[float, float]:
    """(mean, variance) of J under the null, the variance corrected for ``ties`` (the sizes
    of the tied groups of pooled values; Hollander & Wolfe eq. 6.19)."""
    n = sizes.sum()
    mean = (n**2 - (sizes**2).sum()) / 4

    def spread(k):
        return (k * (k - 1) * (2 * k + 5)).sum()

    variance = (n * (n - 1) * (2 * n + 5) - spread(sizes) - spread(ties)) / 72
    variance += (
        (sizes * (sizes - 1) * (sizes - 2)).sum()
        * (ties * (ties - 1) * (ties - 2)).sum()
        / (36 * n * (n - 1) * (n - 2))
    )
    variance += (sizes * (sizes - 1)).sum() * (ties * (ties - 1)).sum() / (8 * n * (n - 1))
    return float(mean), float(variance)


def _clean(groups: Sequence[Sequence[float]]) -> list[np.ndarray]:
    arrays = [np.asarray(g, float) for g in groups]
    return [a[np.isfinite(a)] for a in arrays]


def jonckheere_terpstra(groups: Sequence[Sequence[float]], alternative: str = "increasing") -> RankTest:
    """The Jonckheere-Terpstra test that values rise along ``groups`` (``alternative``
    "increasing"), fall ("decreasing") or either ("two-sided"); J counts the rises (module
    doc). Exact p without ties, the normal approximation with them; NaN p with fewer than
    two non-empty groups."""
    arrays = [a for a in _clean(groups) if a.size]
    if len(arrays) < 2:
        return RankTest(float("nan"), float("nan"), EXACT)
    j = jt_statistic(arrays)
    pooled = np.concatenate(arrays)
    _, counts = np.unique(pooled, return_counts=True)
    sizes = np.array([a.size for a in arrays], float)
    if (counts == 1).all():
        pmf = jt_null([a.size for a in arrays])
        k = int(round(j))
        upper, lower = float(pmf[k:].sum()), float(pmf[: k + 1].sum())
        method = EXACT
    else:
        if pooled.size < 3 or (counts == pooled.size).all():
            return RankTest(j, 1.0, NORMAL)
        mean, variance = _jt_moments(sizes, counts.astype(float))
        z = (j - mean) / math.sqrt(variance)
        upper, lower = float(stats.norm.sf(z)), float(stats.norm.cdf(z))
        method = NORMAL
    p = {"increasing": upper, "decreasing": lower}.get(alternative, min(1.0, 2 * min(upper, lower)))
    return RankTest(j, min(1.0, p), method)


def mann_whitney(a: Sequence[float], b: Sequence[float], alternative: str = "two-sided") -> RankTest:
    """Mann-Whitney U of ``a`` over ``b`` (#(a > b) + ties / 2) with p for ``alternative``:
    "greater" (a above b), "less" or "two-sided"; exact without ties (``jonckheere_terpstra``
    of the groups (b, a))."""
    direction = {"greater": "increasing", "less": "decreasing"}.get(alternative, "two-sided")
    return jonckheere_terpstra([b, a], direction)


def holm(p_values: Sequence[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values: the k-th smallest times (m - k + 1), made
    non-decreasing and capped at 1; NaN p-values stay NaN and are not counted in m."""
    p = np.asarray(p_values, float)
    adjusted = np.full(p.shape, np.nan)
    valid = np.flatnonzero(np.isfinite(p))
    order = valid[np.argsort(p[valid], kind="stable")]
    m, running = order.size, 0.0
    for rank, index in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[index]))
        adjusted[index] = running
    return adjusted
