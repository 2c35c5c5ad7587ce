"""Checks of the statistics by simulation, at the n the study publishes (docs/analysis.md):

- ``interval_coverage``: the share of simulated samples of n run values whose 95% interval
  of the mean holds the true mean, for the t interval the report uses and, for comparison,
  the percentile bootstrap;
- ``power_calibration``: for a known effect (A12, normal run values), the true power of a
  study of ``study_n`` runs per treatment against what ``analysis.power`` estimates from
  simulated pilots of ``pilot_n`` runs: the mean estimate, the share of pilots whose
  estimate is above the true power, and the share that report the target or more.

The tests run them small (tests/analysis/test_calibration.py); ``python -m
softevo.analysis.calibration`` prints the tables of docs/analysis.md (a few minutes).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pandas as pd
from scipy import stats

from softevo.analysis.power import a12_of_shift, pilot_power
from softevo.analysis.stats_tables import t_interval
from softevo.evolution.stats import bootstrap_ci

Sampler = Callable[[np.random.Generator, tuple[int, int]], np.ndarray]

# (name, sampler of shape (trials, n), true mean)
DISTRIBUTIONS: dict[str, tuple[Sampler, float]] = {
    "normal": (lambda rng, shape: rng.standard_normal(shape), 0.0),
    "uniform": (lambda rng, shape: rng.uniform(0, 1, shape), 0.5),
    "exponential": (lambda rng, shape: rng.exponential(1.0, shape), 1.0),
    "lognormal (sigma 1)": (lambda rng, shape: rng.lognormal(0.0, 1.0, shape), math.exp(0.5)),
}


def interval_coverage(method: str, distribution: str, n: int, trials: int, seed: int = 0) -> float:
    """Share of ``trials`` samples of n values whose 95% interval (``method`` ``t`` or
    ``percentile bootstrap``, 2,000 resamples) holds the distribution's mean."""
    sampler, mean = DISTRIBUTIONS[distribution]
    rng = np.random.default_rng(seed)
    samples = sampler(rng, (trials, n))
    hits = 0
    for values in samples:
        if method == "t":
            _, low, high = t_interval(values)
        else:
            _, low, high = bootstrap_ci(values, rng, n_resamples=2_000)
        hits += low <= mean <= high
    return hits / trials


def true_power(shift: float, n: int, alpha: float, studies: int, seed: int) -> float:
    """Share of simulated studies (n runs of N(shift, 1) against n of N(0, 1)) whose
    two-sided Mann-Whitney p is below ``alpha``: drawn apart from ``analysis.power``'s."""
    rng = np.random.default_rng([seed, 7919])
    a, b = rng.standard_normal((studies, n)) + shift, rng.standard_normal((studies, n))
    return float(np.mean(stats.mannwhitneyu(a, b, axis=1).pvalue < alpha))


def power_calibration(
    a12: float, pilot_n: int = 3, study_n: int = 7, alpha: float = 0.05 / 10, pilots: int = 200,
    target: float = 0.8, seed: int = 0,
) -> dict:  # fmt: skip
    """The true power of the design at the effect ``a12`` and what ``analysis.power``
    estimates from ``pilots`` simulated pilots (see the module doc)."""
    shift = math.sqrt(2) * stats.norm.ppf(a12)
    truth = true_power(shift, study_n, alpha, 20_000, seed)
    rng = np.random.default_rng([seed, 1])
    estimates = np.array(
        [
            pilot_power(
                rng.standard_normal(pilot_n) + shift, rng.standard_normal(pilot_n), study_n, alpha, seed
            )
            for _ in range(pilots)
        ]
    )
    low, point = estimates[:, 0], estimates[:, 1]
    return {
        "A12": a12,
        "true power": truth,
        "mean estimate": float(low.mean()),
        "pilots above the true power": float(np.mean(low > truth + 0.02)),
        "pilots reporting the target": float(np.mean(low >= target)),
        "mean estimate at the point estimate": float(point.mean()),
        "pilots reporting the target at the point estimate": float(np.mean(point >= target)),
    }


def coverage_table(n: int = 7, trials: int = 4_000) -> pd.DataFrame:
    """Coverage of both intervals at n over every distribution of ``DISTRIBUTIONS``."""
    rows = [
        {
            "distribution": name,
            "t": interval_coverage("t", name, n, trials),
            "percentile bootstrap": interval_coverage("percentile bootstrap", name, n, trials),
        }
        for name in DISTRIBUTIONS
    ]
    return pd.DataFrame(rows)


def calibration_table(effects=(0.71, 0.86, 0.96), pilots: int = 500, **options) -> pd.DataFrame:
    """``power_calibration`` at each effect."""
    return pd.DataFrame([power_calibration(a12, pilots=pilots, **options) for a12 in effects])


if __name__ == "__main__":
    pd.set_option("display.width", 200)
    print(coverage_table().round(3).to_string(index=False))
    print(calibration_table().round(3).to_string(index=False))
    print(calibration_table(alpha=0.05).round(3).to_string(index=False))
    print(f"A12 of shift 1: {a12_of_shift(1.0):.3f}")
