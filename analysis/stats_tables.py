"""Statistics over DataFrames (paper section 2.5), built on ``evolution.stats``.

- The unit is the run: every test compares one value per run (its population's best
  distance at the generation, or its population's mean of a trait then), n = repetitions.
  Pooling the individuals of several runs would treat correlated samples as independent.
- Matched generations (``analysis.matching``): each comparison names its generation, the
  ``generation`` column. Static treatments are compared at the static treatments' common
  last generation, a transition against a static treatment at the last generation both
  have stored; start vs end is generation 0 against the treatment's end generation.
- Confidence intervals: percentile bootstrap 95% intervals of the mean over repetitions.
- Mann-Whitney U (two-sided) between treatments, and between the start and the end of a
  treatment (a = start, b = end).
- Effect sizes: Vargha-Delaney ``A12`` = P(a > b) + P(a = b) / 2 over runs, and
  ``difference`` = mean_a - mean_b with its 95% percentile bootstrap interval
  (``difference_low``, ``difference_high``; each sample resampled on its own, seeded per row
  from the table's seed, so the same data and seed give the same table).
- Bonferroni: p-values are multiplied by the number of comparisons in their family and
  capped at 1. A family is one metric of one kind of comparison: e.g. the "symmetry"
  comparisons between treatments form one family, the start-vs-end comparisons of
  "symmetry" another.

Which treatments are compared: those that differ in exactly one factor, environment
schedule or stiffness (``comparison_pairs``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from softevo.analysis.data import TRAITS, ExperimentData
from softevo.analysis.matching import comparison_pairs
from softevo.evolution.stats import (
    bonferroni,
    bootstrap_ci,
    bootstrap_difference,
    mann_whitney,
    vargha_delaney,
)

CONFIDENCE = 0.95
N_RESAMPLES = 10_000
CURVE_RESAMPLES = 2_000  # per generation of the fitness curves
MAX_CURVE_POINTS = 500
ALPHA = 0.05
STAT_COLUMNS = [
    "comparison",
    "metric",
    "unit",
    "a",
    "b",
    "generation",
    "n_a",
    "n_b",
    "mean_a",
    "mean_b",
    "median_a",
    "median_b",
    "U",
    "p",
    "p_bonferroni",
    "significance",
    "A12",
    "difference",
    "difference_low",
    "difference_high",
]
METRICS = ("best_distance", *TRAITS)


def significance_mark(p: float, alpha: float = ALPHA) -> str:
    """``***`` (p < alpha/50), ``**`` (p < alpha/5), ``*`` (p < alpha) or ``ns``."""
    if not np.isfinite(p):
        return "n/a"
    for mark, limit in (("***", alpha / 50), ("**", alpha / 5), ("*", alpha)):
        if p < limit:
            return mark
    return "ns"


def ci_table(
    frame: pd.DataFrame,
    value: str,
    by: str | Sequence[str],
    rng: np.random.Generator,
    confidence: float = CONFIDENCE,
    n_resamples: int = N_RESAMPLES,
) -> pd.DataFrame:
    """Per group of ``by``: n, mean, low, high of column ``value`` (bootstrap CI of the mean).

    Missing values are dropped; a group with no value gets NaN mean and bounds.
    """
    keys = [by] if isinstance(by, str) else list(by)
    rows = []
    for key, group in frame.groupby(keys, sort=False, dropna=False):
        values = group[value].dropna().to_numpy(dtype=float)
        if values.size:
            mean, low, high = bootstrap_ci(values, rng, confidence, n_resamples)
        else:
            mean = low = high = float("nan")
        key = key if isinstance(key, tuple) else (key,)
        rows.append(
            {
                **dict(zip(keys, key, strict=True)),
                "n": int(values.size),
                "mean": mean,
                "low": low,
                "high": high,
            }
        )
    return pd.DataFrame(rows, columns=[*keys, "n", "mean", "low", "high"])


def compare(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """(U, two-sided p) of Mann-Whitney U; NaN for an empty sample."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size == 0 or b.size == 0:
        return float("nan"), float("nan")
    return mann_whitney(a, b)


def adjust_families(table: pd.DataFrame, family: Sequence[str] = ("comparison", "metric")) -> None:
    """Fill ``p_bonferroni`` and ``significance`` in place, Bonferroni within each family
    (rows sharing the ``family`` columns; NaN p-values are not counted)."""
    table["p_bonferroni"] = np.nan
    for _, group in table.groupby(list(family), sort=False):
        valid = group["p"].notna()
        if valid.any():
            index = group.index[valid]
            table.loc[index, "p_bonferroni"] = bonferroni(group.loc[valid, "p"].to_numpy())
    table["significance"] = [significance_mark(p) for p in table["p_bonferroni"]]


def _comparison_row(kind: str, metric: str, generation, names, a, b, rng: np.random.Generator) -> dict:
    a = pd.Series(a, dtype=float).dropna()
    b = pd.Series(b, dtype=float).dropna()
    u, p = compare(a, b)
    if len(a) and len(b):
        a12 = vargha_delaney(a, b)
        difference, low, high = bootstrap_difference(a, b, rng, CONFIDENCE, N_RESAMPLES)
    else:
        a12 = difference = low = high = float("nan")
    return {
        "comparison": kind,
        "metric": metric,
        "unit": "run",
        "a": names[0],
        "b": names[1],
        "generation": generation,
        "n_a": len(a),
        "n_b": len(b),
        "mean_a": a.mean(),
        "mean_b": b.mean(),
        "median_a": a.median(),
        "median_b": b.median(),
        "U": u,
        "p": p,
        "A12": a12,
        "difference": difference,
        "difference_low": low,
        "difference_high": high,
    }


class _Values:
    """``ExperimentData.run_values`` per generation, each computed once."""

    def __init__(self, data: ExperimentData):
        self.data, self.cache = data, {}

    def __call__(self, generation: int | None, treatment: str, metric: str) -> pd.Series:
        if generation is None:
            return pd.Series(dtype=float)
        if generation not in self.cache:
            self.cache[generation] = self.data.run_values(generation)
        values = self.cache[generation]
        return values.loc[values["treatment"] == treatment, metric]


def _row_rng(seed: int, k: int) -> np.random.Generator:
    return np.random.default_rng([seed, k])


def best_distance_per_run(data: ExperimentData) -> pd.DataFrame:
    """Per run: treatment, repetition, generation and best_distance at its treatment's
    display generation (``analysis.matching``)."""
    values = data.display_run_values()
    return values[["run_id", "treatment", "repetition", "generation", "best_distance"]]


def treatment_comparisons(
    data: ExperimentData, metrics: Sequence[str] = METRICS, seed: int = 0
) -> pd.DataFrame:
    """Mann-Whitney U, A12 and the bootstrap difference between treatment pairs
    (``comparison_pairs``) over runs, each pair at its generation; Bonferroni per metric."""
    values = _Values(data)
    rows = []
    for metric in metrics:
        for a, b in comparison_pairs(data.treatments):
            generation = data.pair_generation(a, b)
            rows.append(
                _comparison_row(
                    "between treatments",
                    metric,
                    generation,
                    (a, b),
                    values(generation, a, metric),
                    values(generation, b, metric),
                    _row_rng(seed, len(rows)),
                )
            )
    return _finish(rows)


def start_end_comparisons(
    data: ExperimentData, metrics: Sequence[str] = TRAITS, seed: int = 1
) -> pd.DataFrame:
    """The same tests of each trait between generation 0 (a = start) and the treatment's end
    generation (b = end, named in ``generation``) over its runs; Bonferroni per metric across
    treatments."""
    values = _Values(data)
    rows = []
    for metric in metrics:
        for name in data.treatment_names:
            end = data.end_generation(name)
            rows.append(
                _comparison_row(
                    "start vs end",
                    metric,
                    end,
                    (f"{name} start", f"{name} end"),
                    values(0, name, metric),
                    values(end, name, metric),
                    _row_rng(seed, len(rows)),
                )
            )
    return _finish(rows)


def _finish(rows: list[dict]) -> pd.DataFrame:
    table = pd.DataFrame(rows, columns=[c for c in STAT_COLUMNS if c not in ("p_bonferroni", "significance")])
    table["generation"] = table["generation"].astype("Int64")
    adjust_families(table)
    return table[STAT_COLUMNS]


def statistics_table(data: ExperimentData, seed: int = 0) -> pd.DataFrame:
    """All tests of the report: between treatments, then start vs end (``seed`` seeds the
    bootstrap intervals of the differences)."""
    return pd.concat(
        [treatment_comparisons(data, seed=seed), start_end_comparisons(data, seed=seed + 1)],
        ignore_index=True,
    )


def shown_generations(data: ExperimentData) -> list[tuple[str, int]]:
    """(treatment, generation) for each treatment at its display generation and at every
    generation it is compared at with another treatment, in treatment order."""
    found: dict[str, set[int]] = {name: set() for name in data.treatment_names}
    for name in data.treatment_names:
        found[name].add(data.display_generation(name))
    for a, b in comparison_pairs(data.treatments):
        generation = data.pair_generation(a, b)
        found[a].add(generation)
        found[b].add(generation)
    return [
        (name, g) for name in data.treatment_names for g in sorted(x for x in found[name] if x is not None)
    ]


def summary_table(data: ExperimentData, rng: np.random.Generator) -> pd.DataFrame:
    """Per metric, treatment and generation (``shown_generations``): repetitions, mean and
    bootstrap CI over runs of the run values (best distance, or population mean of a
    trait)."""
    values = _Values(data)
    parts = []
    for name, generation in shown_generations(data):
        for metric in METRICS:
            series = values(generation, name, metric)
            parts.append(
                pd.DataFrame({"metric": metric, "treatment": name, "generation": generation, "value": series})
            )
            if series.empty:  # keep the row: a group with no value gets NaN
                parts[-1] = pd.DataFrame(
                    {"metric": [metric], "treatment": [name], "generation": [generation], "value": [np.nan]}
                )
    frame = pd.concat(parts, ignore_index=True)
    table = ci_table(frame, "value", ["metric", "treatment", "generation"], rng)
    order = {name: k for k, name in enumerate(data.treatment_names)}
    metric_order = {m: k for k, m in enumerate(METRICS)}
    table["generation"] = table["generation"].astype("Int64")
    table = table.sort_values(
        ["metric", "treatment", "generation"],
        key=lambda col: (
            col.map(metric_order)
            if col.name == "metric"
            else (col.map(order) if col.name == "treatment" else col)
        ),
        kind="stable",
    )
    return table.reset_index(drop=True)


def plotted_generations(generations: np.ndarray, switches: Sequence[int], max_points: int) -> np.ndarray:
    """At most about ``max_points`` generations spread evenly from first to last, plus the
    generations on either side of each environment switch (so the jump stays sharp)."""
    generations = np.unique(generations)
    if len(generations) <= max_points:
        return generations
    spread = generations[np.unique(np.linspace(0, len(generations) - 1, max_points).round().astype(int))]
    near_switch = [g for s in switches for g in (s - 1, s)]
    return np.intersect1d(generations, np.union1d(spread, near_switch))


def fitness_curves(
    data: ExperimentData, rng: np.random.Generator, max_points: int = MAX_CURVE_POINTS
) -> pd.DataFrame:
    """Per treatment and generation: mean best distance over repetitions with its bootstrap
    CI (columns treatment, generation, n, mean, low, high). Long runs are thinned to about
    ``max_points`` generations (``plotted_generations``)."""
    frame = data.generations
    switches = [int(s) for s in data.treatments["switch_at"].dropna()]
    kept = plotted_generations(frame["generation"].to_numpy(), switches, max_points)
    frame = frame[frame["generation"].isin(kept)]
    return ci_table(frame, "best_distance", ["treatment", "generation"], rng, n_resamples=CURVE_RESAMPLES)
